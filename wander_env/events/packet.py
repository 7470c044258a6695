"""One step's events as an opaque value: what ``info["events"]`` holds.

The events of a step are a structured array (:data:`wander_env.events.EVENT_DTYPE`)
whose length changes from step to step. Gymnasium's generic tools cannot carry such an
array in ``info``: vector envs stack every ``ndarray`` of ``info`` assuming one shape
for all envs ("could not broadcast (484,) into (1936,)"), and ``check_env`` compares
arrays with ``np.allclose``, which has no meaning for a structured dtype. An
:class:`EventPacket` is an ordinary object to them: vector envs gather one per env in an
object array, ``check_env`` compares two with ``==`` (event for event), and it pickles.

The packet has no capacity: every event of the step is in it, nothing is padded or
dropped. ``packet.events`` (or ``np.asarray(packet)``) is the array itself.

Examples:
    >>> import numpy as np
    >>> from wander_env.events import make_events
    >>> packet = EventPacket(make_events(x=[1, 2], y=[3, 4], t=[10, 20], p=[1, 0]))
    >>> len(packet), packet.events["x"].tolist(), np.asarray(packet)["t"].tolist()
    (2, [1, 2], [10, 20])
    >>> vector_info = np.full(2, None, dtype=object)  # what a vector env builds
    >>> vector_info[0] = packet
    >>> vector_info[0] == packet
    True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wander_env.events import EVENT_DTYPE


@dataclass(frozen=True, eq=False)
class EventPacket:
    """The events of one step (a structured :data:`EVENT_DTYPE` array) as one value."""

    events: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.events, np.ndarray) or self.events.dtype != EVENT_DTYPE:
            got = getattr(self.events, "dtype", type(self.events).__name__)
            raise TypeError(f"EventPacket.events must be an EVENT_DTYPE array, got {got}")

    def __len__(self) -> int:
        return len(self.events)

    def __array__(self, dtype: np.dtype | None = None, copy: bool | None = None) -> np.ndarray:
        same = dtype is None or np.dtype(dtype) == self.events.dtype
        if copy is False and not same:
            raise ValueError(f"EventPacket: a {dtype} view of {self.events.dtype} needs a copy")
        if copy:
            return self.events.astype(dtype or self.events.dtype, copy=True)
        return self.events if same else self.events.astype(dtype)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, EventPacket) and np.array_equal(self.events, other.events)

    def __hash__(self) -> int:
        return hash(self.events.tobytes())

    def __repr__(self) -> str:
        n = len(self.events)
        if n == 0:
            return "EventPacket(0 events)"
        t = self.events["t"]
        return f"EventPacket({n} events, t {int(t[0])}..{int(t[-1])} µs)"


__all__ = ["EventPacket"]
