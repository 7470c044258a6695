"""Wander's offline chip check: does a sinabs network fit Speck's documented limits?

sinabs' mapper checks memory only (it accepted a 128×128 output and a 31 px kernel,
both of which the datasheet forbids; issue 35). :func:`check_network` checks what the
documents state (:class:`SpeckLimits`, each value with its source) before any
deployment and refuses with one line naming the layer and the limit, e.g.
``layer 1 (conv 31x31): kernel 31 px > Speck's 16 px limit``; :func:`violations`
lists every breach. Pure: no samna, no sinabs backend.

A network is a ``torch.nn.Sequential`` of Speck cores, each ``Conv2d`` → an IAF layer
(``sinabs.layers.IAF`` or ``IAFSqueeze``) → optionally ``SumPool2d``, the next core's
input the previous one's output (fan-out 1; the fan-out limit is checked on
:attr:`CoreLayer.destinations`). The memory of a core is counted as sinabs'
``DynapcnnLayer.memory_summary`` documents it (read in sinabs 3.1.3
``backend/dynapcnn/dynapcnn_layer.py``), every factor rounded up to a power of two:

* kernel words ``c_in · 2^(⌈log2(k_h k_w)⌉ + ⌈log2 c_out⌉)``,
* neuron words ``c_out · 2^(⌈log2 h_out⌉ + ⌈log2 w_out⌉)``,

and the layers are assigned to distinct cores whose kernel and neuron memories
(:attr:`SpeckLimits.kernel_memory`, :attr:`SpeckLimits.neuron_memory`) hold them.

Examples:
    >>> from agents.speck_front import SpeckFrontParams, build_front
    >>> report = check_network(build_front(SpeckFrontParams()), (2, 128, 128))
    >>> [(lay.neuron_memory, lay.kernel_memory) for lay in report.layers]
    [(8192, 512), (32768, 4096), (4096, 2048)]
    >>> report.cores
    (0, 1, 2)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sinabs.layers as sl
from torch import nn

from wander_env.readout import SPECK_DVS_SIZE

__all__ = [
    "CoreLayer",
    "NetworkReport",
    "SpeckLimitError",
    "SpeckLimits",
    "check_network",
    "conv_out",
    "core_layers",
    "kernel_memory",
    "neuron_memory",
    "signed_range",
    "violations",
]

_KI = 1024


class SpeckLimitError(ValueError):
    """A network breaks one of Speck's limits; the message is one line naming the layer."""


@dataclass(frozen=True)
class SpeckLimits:
    """Speck's documented limits (Speck Dev Kit Datasheet, Aug 2023; sinabs
    ``docs/speck/``; /work/shared/DESIGN.md "Speck"):

    - ``cores`` 9 (conv → IAF → sum-pool each); ``max_input_px`` 128 (the pixel array);
    - ``max_output_px`` 64: each core's neuron array is at most 64×64;
    - ``max_kernel_px`` 16, ``max_padding`` 7, ``strides`` 1/2/4/8, ``pools`` 1/2/4;
    - ``max_fan_out`` 2 destinations per core; ``max_features`` 1024 channels;
    - ``kernel_memory`` / ``neuron_memory`` words per core: 16 Ki/64 Ki (cores 0–2),
      32 Ki/32 Ki (3–4), 64 Ki/16 Ki (5–6), 16 Ki/16 Ki (7–8);
    - ``weight_bits`` 8 (weights and biases: sinabs' discretisation gives the bias the
      weights' precision), ``state_bits`` 16 (membrane, thresholds);
    - IAF neurons only, one threshold pair per layer, ``threshold_low`` ≠ 0 (a known bug).
    """

    cores: int = 9
    max_input_px: int = SPECK_DVS_SIZE[0]
    max_output_px: int = 64
    max_kernel_px: int = 16
    max_padding: int = 7
    strides: tuple[int, ...] = (1, 2, 4, 8)
    pools: tuple[int, ...] = (1, 2, 4)
    max_fan_out: int = 2
    max_features: int = 1024
    kernel_memory: tuple[int, ...] = (16, 16, 16, 32, 32, 64, 64, 16, 16)
    neuron_memory: tuple[int, ...] = (64, 64, 64, 32, 32, 16, 16, 16, 16)
    weight_bits: int = 8
    state_bits: int = 16

    def __post_init__(self) -> None:
        for name in ("kernel_memory", "neuron_memory"):
            if len(getattr(self, name)) != self.cores:
                raise ValueError(f"SpeckLimits.{name} needs one entry per core ({self.cores})")


def _pow2_bits(n: int) -> int:
    return math.ceil(math.log2(n)) if n > 1 else 0


def kernel_memory(c_in: int, c_out: int, kh: int, kw: int) -> int:
    """Kernel memory words of a core: ``c_in · 2^(⌈log2(kh kw)⌉ + ⌈log2 c_out⌉)``.

    >>> kernel_memory(2, 8, 15, 15), kernel_memory(2, 2, 9, 9)
    (4096, 512)
    """
    return c_in * 2 ** (_pow2_bits(kh * kw) + _pow2_bits(c_out))


def neuron_memory(f: int, h: int, w: int) -> int:
    """Neuron memory words of a core: ``f · 2^(⌈log2 h⌉ + ⌈log2 w⌉)``.

    >>> neuron_memory(8, 64, 64), neuron_memory(8, 128, 128)
    (32768, 131072)
    """
    return f * 2 ** (_pow2_bits(h) + _pow2_bits(w))


@dataclass(frozen=True)
class CoreLayer:
    """One core of a network: its conv geometry, neuron layer and pooling, as read from
    the modules (:func:`core_layers`). ``in_shape`` and ``out_shape`` are the neuron
    array's input ``(c, h, w)`` and output ``(f, h, w)`` (before pooling)."""

    index: int
    in_shape: tuple[int, int, int]
    out_shape: tuple[int, int, int]
    kernel: tuple[int, int]
    stride: tuple[int, int]
    padding: tuple[int, int] | str
    pool: int
    neuron: str
    thresholds: tuple[np.ndarray, np.ndarray | None]
    weight: np.ndarray
    bias: np.ndarray | None
    destinations: tuple[int, ...]

    @property
    def label(self) -> str:
        return f"layer {self.index} (conv {self.kernel[0]}x{self.kernel[1]})"

    @property
    def kernel_memory(self) -> int:
        return kernel_memory(self.in_shape[0], self.out_shape[0], *self.kernel)

    @property
    def neuron_memory(self) -> int:
        return neuron_memory(*self.out_shape)


def _pair(v: int | tuple[int, ...]) -> tuple[int, int]:
    return (int(v), int(v)) if isinstance(v, int) else (int(v[0]), int(v[1]))


def conv_out(n: int, k: int, s: int, p: int) -> int:
    """The output size of a convolution over ``n`` pixels: kernel ``k``, stride ``s``,
    padding ``p`` on each side.

    >>> conv_out(128, 9, 2, 4)  # the Speck front end's first core: 128 -> 64
    64
    """
    return (n + 2 * p - k) // s + 1


def signed_range(bits: int) -> tuple[int, int]:
    """The integers a ``bits``-bit two's-complement register holds.

    >>> signed_range(SpeckLimits().weight_bits)
    (-128, 127)
    """
    return -(2 ** (bits - 1)), 2 ** (bits - 1) - 1


def core_layers(model: nn.Sequential, input_shape: Sequence[int]) -> list[CoreLayer]:
    """The cores of ``model`` (conv → neuron layer → optional ``SumPool2d`` each) fed
    ``input_shape`` ``(c, h, w)``; a module in any other place raises
    :class:`SpeckLimitError` naming it."""
    mods = list(model)
    shape = tuple(int(v) for v in input_shape)
    out: list[CoreLayer] = []
    i = 0
    while i < len(mods):
        conv = mods[i]
        idx = len(out)
        if not isinstance(conv, nn.Conv2d):
            raise SpeckLimitError(
                f"layer {idx}: {type(conv).__name__} where a core needs nn.Conv2d "
                "(conv -> IAF -> sum-pool)"
            )
        kernel, stride = _pair(conv.kernel_size), _pair(conv.stride)
        label = f"layer {idx} (conv {kernel[0]}x{kernel[1]})"
        if i + 1 >= len(mods) or not isinstance(mods[i + 1], sl.StatefulLayer):
            nxt = type(mods[i + 1]).__name__ if i + 1 < len(mods) else "nothing"
            raise SpeckLimitError(f"{label}: followed by {nxt}; a core needs a spiking layer")
        spk = mods[i + 1]
        pool = 1
        step = 2
        if i + 2 < len(mods) and isinstance(mods[i + 2], (sl.SumPool2d, nn.AvgPool2d)):
            pk = _pair(mods[i + 2].kernel_size)
            if not isinstance(mods[i + 2], sl.SumPool2d) or pk[0] != pk[1]:
                raise SpeckLimitError(f"{label}: pooling must be a square SumPool2d")
            pool, step = pk[0], 3
        padding = conv.padding if isinstance(conv.padding, str) else _pair(conv.padding)
        c, h, w = shape
        if conv.in_channels != c:
            raise SpeckLimitError(f"{label}: takes {conv.in_channels} channels, is fed {c}")
        if padding == "same":  # torch: stride 1, the output the input's size
            o_h, o_w = h, w
        else:
            o_h = conv_out(h, kernel[0], stride[0], padding[0])
            o_w = conv_out(w, kernel[1], stride[1], padding[1])
        out_shape = (int(conv.out_channels), o_h, o_w)
        thr = np.asarray(spk.spike_threshold.detach().cpu().numpy(), np.float64)
        low = getattr(spk, "min_v_mem", None)
        low_a = None if low is None else np.asarray(np.asarray(low, dtype=np.float64))
        bias = None if conv.bias is None else conv.bias.detach().cpu().numpy().astype(np.float64)
        is_last = i + step >= len(mods)
        out.append(
            CoreLayer(
                index=idx,
                in_shape=(c, h, w),
                out_shape=out_shape,
                kernel=kernel,
                stride=stride,
                padding=padding,
                pool=pool,
                neuron=type(spk).__name__,
                thresholds=(thr, low_a),
                weight=conv.weight.detach().cpu().numpy().astype(np.float64),
                bias=bias,
                destinations=() if is_last else (idx + 1,),
            )
        )
        shape = (out_shape[0], o_h // pool, o_w // pool)
        i += step
    return out


def _is_int_in(a: np.ndarray, bits: int) -> bool:
    lo, hi = signed_range(bits)
    return bool(np.all(np.round(a) == a) and a.min(initial=0) >= lo and a.max(initial=0) <= hi)


def _layer_violations(lay: CoreLayer, lim: SpeckLimits, neuron_is_iaf: bool) -> list[str]:
    v: list[str] = []
    tag = lay.label
    if not neuron_is_iaf:
        v.append(f"{tag}: {lay.neuron} neurons; Speck's cores have IAF only")
    k = max(lay.kernel)
    if lay.kernel[0] != lay.kernel[1]:
        v.append(f"{tag}: kernel {lay.kernel[0]}x{lay.kernel[1]} is not square")
    if k > lim.max_kernel_px:
        v.append(f"{tag}: kernel {k} px > Speck's {lim.max_kernel_px} px limit")
    bad_stride = [s for s in lay.stride if s not in lim.strides]
    if bad_stride:
        v.append(f"{tag}: stride {bad_stride[0]} not in Speck's {lim.strides}")
    if isinstance(lay.padding, str):
        if any(kk % 2 == 0 for kk in lay.kernel):
            v.append(f"{tag}: padding 'same' with an even kernel is asymmetric; Speck pads evenly")
        pads = (lay.kernel[0] // 2, lay.kernel[1] // 2)
    else:
        pads = lay.padding
    if max(pads) > lim.max_padding:
        v.append(f"{tag}: padding {max(pads)} px > Speck's {lim.max_padding} px limit")
    if lay.pool not in lim.pools:
        v.append(f"{tag}: sum-pool {lay.pool} not in Speck's {lim.pools}")
    f, h, w = lay.out_shape
    if max(h, w) > lim.max_output_px:
        v.append(f"{tag}: output {h}x{w} > Speck's {lim.max_output_px}x{lim.max_output_px} limit")
    if max(f, lay.in_shape[0]) > lim.max_features:
        v.append(f"{tag}: {max(f, lay.in_shape[0])} features > Speck's {lim.max_features}")
    if len(lay.destinations) > lim.max_fan_out:
        v.append(f"{tag}: fan-out {len(lay.destinations)} > Speck's {lim.max_fan_out}")
    if not _is_int_in(lay.weight, lim.weight_bits):
        v.append(f"{tag}: weights are not {lim.weight_bits}-bit integers (quantise first)")
    if lay.bias is not None and not _is_int_in(lay.bias, lim.weight_bits):
        v.append(f"{tag}: biases (leaks) are not {lim.weight_bits}-bit integers")
    thr, low = lay.thresholds
    if thr.size != 1 or (low is not None and low.size != 1):
        v.append(f"{tag}: {thr.size} thresholds; Speck has one threshold pair per layer")
    elif not _is_int_in(thr, lim.state_bits) or (
        low is not None and not _is_int_in(low, lim.state_bits)
    ):
        v.append(f"{tag}: thresholds are not {lim.state_bits}-bit integers")
    elif low is not None and float(low) == 0.0:
        v.append(f"{tag}: threshold_low (min_v_mem) 0 hits Speck's known threshold_low bug")
    return v


@dataclass(frozen=True)
class NetworkReport:
    """A network that fits: its cores and the chip core each goes to."""

    layers: tuple[CoreLayer, ...]
    cores: tuple[int, ...]


def _assign(layers: Sequence[CoreLayer], lim: SpeckLimits) -> tuple[int, ...] | None:
    """Distinct cores holding each layer's kernel and neuron memory (the first such
    assignment in core order, by backtracking), or None."""
    fits = [
        [
            c
            for c in range(lim.cores)
            if lay.kernel_memory <= lim.kernel_memory[c] * _KI
            and lay.neuron_memory <= lim.neuron_memory[c] * _KI
        ]
        for lay in layers
    ]

    def place(i: int, used: tuple[int, ...]) -> tuple[int, ...] | None:
        if i == len(layers):
            return used
        for c in fits[i]:
            if c not in used:
                found = place(i + 1, (*used, c))
                if found is not None:
                    return found
        return None

    return place(0, ())


def _ki(words: int) -> str:
    return f"{words / _KI:g} Ki"


def violations(
    model: nn.Sequential, input_shape: Sequence[int], limits: SpeckLimits | None = None
) -> list[str]:
    """Every breach of Speck's limits by ``model`` fed ``input_shape`` ``(c, h, w)``,
    one line each, in layer order (empty: it fits)."""
    lim = limits if limits is not None else SpeckLimits()
    c, h, w = (int(v) for v in input_shape)
    out: list[str] = []
    if max(h, w) > lim.max_input_px:
        out.append(f"input {h}x{w} > Speck's {lim.max_input_px}x{lim.max_input_px} limit")
    if c > lim.max_features:
        out.append(f"input: {c} features > Speck's {lim.max_features}")
    mods = list(model)
    layers = core_layers(model, input_shape)
    spiking = [m for m in mods if isinstance(m, sl.StatefulLayer)]
    for lay, spk in zip(layers, spiking, strict=True):
        out += _layer_violations(lay, lim, isinstance(spk, sl.IAF))
        kmax = max(lim.kernel_memory) * _KI
        nmax = max(lim.neuron_memory) * _KI
        if lay.neuron_memory > nmax:
            out.append(
                f"{lay.label}: neuron memory {_ki(lay.neuron_memory)} words > Speck's "
                f"largest core ({_ki(nmax)})"
            )
        elif lay.kernel_memory > kmax:
            out.append(
                f"{lay.label}: kernel memory {_ki(lay.kernel_memory)} words > Speck's "
                f"largest core ({_ki(kmax)})"
            )
        elif _assign([lay], lim) is None:
            out.append(
                f"{lay.label}: kernel {_ki(lay.kernel_memory)} and neuron "
                f"{_ki(lay.neuron_memory)} words fit no single Speck core"
            )
    if len(layers) > lim.cores:
        out.append(f"network: {len(layers)} layers > Speck's {lim.cores} cores")
    elif not out and _assign(layers, lim) is None:
        out.append(
            f"network: no assignment of its {len(layers)} layers to Speck's {lim.cores} "
            "cores fits the kernel/neuron memory table"
        )
    return out


def check_network(
    model: nn.Sequential, input_shape: Sequence[int], limits: SpeckLimits | None = None
) -> NetworkReport:
    """The cores of ``model`` and where they go, or :class:`SpeckLimitError` with the
    first of :func:`violations`."""
    lim = limits if limits is not None else SpeckLimits()
    found = violations(model, input_shape, lim)
    if found:
        raise SpeckLimitError(found[0])
    layers = core_layers(model, input_shape)
    cores = _assign(layers, lim)
    assert cores is not None  # violations() found an assignment
    return NetworkReport(layers=tuple(layers), cores=cores)
