"""One reader for files the user (or someone else) made: bounded, regular files only.

Everything the project reads from a path it did not write in this process goes through
here: scene meshes, MJCF includes and every file they name (nested includes, meshes,
textures, height fields), JSON documents (a result's ``config.json`` and ``run.json``,
a sweep's trial files), ``.npz`` archives (EVIMO sequences, a result's artifacts). The
rules, each checked before the work it bounds:

- **regular files only**: opened with ``O_NONBLOCK`` (a FIFO never blocks the open), then
  ``fstat`` must say a regular file: a FIFO, a device (a link to ``/dev/zero``), a socket
  or a folder is refused;
- **size before reading**: the file's size against its cap, and no more than the cap is
  ever read (a file that grows while read is refused too);
- **inflated size before inflating**: an archive's declared member sizes against the cap,
  and no member inflates past its declared size (a forged header fails its CRC there);
  a PNG texture's width, height and bit depth (its IHDR) before it is decoded;
- **MJCF before compiling**: ``<include>`` depth and count, the product of nested
  ``<replicate>`` counts, the elements the document expands to, built-in textures' and
  height fields' sizes; after compiling, the model's size (bodies, geoms, vertices, ...);
- **JSON nesting before parsing**: a document nested deeper than the cap is one line, not
  a ``RecursionError``.

The caps live in one place, :class:`FileLimits` (the reason for each beside it;
``docs/limits.md`` lists them). A refusal is :class:`UntrustedFileError` (a
``ValueError``): one line, ``FILE: field: what is wrong``.

A :class:`ReadLog` passed explicitly records the SHA-256 of each file read (the run's
provenance: :mod:`experiments.runs.provenance`).

Examples:
    >>> import json, tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.json"
    >>> _ = path.write_text(json.dumps({"a": [1, 2]}))
    >>> log = ReadLog()
    >>> read_json(path, log=log)
    {'a': [1, 2]}
    >>> [(r.size, r.sha256[:12]) for r in log.records]
    [(13, '0bf464f8d802')]
    >>> try:
    ...     read_json("/dev/zero")
    ... except UntrustedFileError as e:
    ...     print(e)
    /dev/zero: not a regular file (a character device): refused
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
import stat
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from wander_env.file_error import FileError

if TYPE_CHECKING:  # (zipfile and ElementTree are imported where used: config.py imports this)
    import xml.etree.ElementTree as ET

    import mujoco
    import numpy as np

__all__ = [
    "LIMITS",
    "FileLimits",
    "FileRecord",
    "MJCFFiles",
    "ReadLog",
    "UntrustedFileError",
    "check_model_size",
    "hash_file",
    "json_nesting",
    "limits_table",
    "load_mjcf",
    "npz_members",
    "open_regular",
    "png_size",
    "read_bytes",
    "read_json",
    "read_npz",
]

MiB = 1 << 20


def _cap(value: int, why: str) -> Any:
    """A field of :class:`FileLimits`: its default and why (``metadata["why"]``)."""
    return field(default=value, metadata={"why": why})


@dataclass(frozen=True)
class FileLimits:
    """The caps on what an untrusted file may cost, each with its reason.

    Together they keep any one file's reading within about 1 GB resident (the bound the
    fault-injection tests hold the CLI to). ``docs/limits.md`` is :func:`limits_table`.
    """

    json_bytes: int = _cap(
        8 * MiB,
        "A JSON document: config.json, run.json (a few kB); a sweep's trial files have "
        "their own cap, 16 MiB (experiments.runs.trials).",
    )
    json_depth: int = _cap(
        64,
        "Lists and objects nested in a JSON document, an event file's `metadata` too (ours "
        "nest 4-6 deep).",
    )
    mjcf_bytes: int = _cap(8 * MiB, "An MJCF file, and all the MJCF files one include brings.")
    include_depth: int = _cap(8, "`<include>` files within files.")
    mjcf_files: int = _cap(1000, "Files one MJCF include may name (MJCF, meshes, textures).")
    replicate_product: int = _cap(
        10_000, "The product of nested `<replicate>` counts: what one element may become."
    )
    mjcf_elements: int = _cap(200_000, "Elements the MJCF files expand to (replicates multiplied).")
    mesh_bytes: int = _cap(
        16 * MiB, "A mesh file (OBJ/STL): an OBJ of ~3.5e5 vertices, which MuJoCo reads in 10-20 s."
    )
    texture_bytes: int = _cap(16 * MiB, "A texture file (PNG) as stored.")
    texture_pixels: int = _cap(
        4096 * 4096,
        "A texture's pixels, decoded (read from its PNG header) or built in (width x height x "
        "faces): MuJoCo holds 3-4 bytes a pixel and the GL driver a copy, ~130 MB at the cap.",
    )
    hfield_cells: int = _cap(4096 * 4096, "A height field's cells (nrow x ncol): 4 bytes each.")
    model_bodies: int = _cap(10_000, "Bodies of a compiled model (a scene builds a few hundred).")
    model_geoms: int = _cap(50_000, "Geoms of a compiled model (a draw call each, every frame).")
    model_vertices: int = _cap(
        4_000_000, "Mesh vertices of a compiled model (12 bytes each, plus normals and faces)."
    )
    model_texture_bytes: int = _cap(
        256 * MiB, "Texture bytes of a compiled model (MuJoCo's copy; the GL driver holds another)."
    )
    npz_bytes: int = _cap(512 * MiB, "An .npz archive as stored.")
    npz_inflated_bytes: int = _cap(
        512 * MiB, "An .npz archive's members inflated, together (their declared sizes)."
    )


#: The limits every reader uses unless its caller passes others.
LIMITS = FileLimits()


def _amount(name: str, value: int) -> str:
    if name.endswith("_bytes") and value % MiB == 0:
        return f"{value // MiB} MiB"
    return f"{value:,}"


def limits_table(limits: FileLimits = LIMITS) -> str:
    """The caps as a Markdown table: name, value, why.

    >>> limits_table().splitlines()[3]
    "| `json_depth` | 64 | Lists and objects nested in a JSON document, an event file's \
`metadata` too (ours nest 4-6 deep). |"
    """
    rows = [
        f"| `{f.name}` | {_amount(f.name, getattr(limits, f.name))} | {f.metadata['why']} |"
        for f in dataclasses.fields(limits)
    ]
    return "\n".join(["| cap | value | why |", "|---|---|---|", *rows])


@dataclass(eq=False, repr=False)
class UntrustedFileError(FileError):
    """A file refused: one line, ``FILE: [field: ]what is wrong``; ``missing`` when there
    is no such file, ``kind`` what it is when it is not a regular file ("a folder", ...)."""

    missing: bool = False
    kind: str | None = None

    def message(self) -> str:
        """``FILE: [FIELD: ]PROBLEM``, its white space folded to single spaces."""
        where = f"{self.field}: " if self.field else ""
        return " ".join(f"{self.path}: {where}{self.problem}".split())


class FileRecord(NamedTuple):
    """One file read: its absolute path, size (bytes) and SHA-256 (hex)."""

    path: str
    size: int
    sha256: str


@dataclass
class ReadLog:
    """The files a piece of work read, in the order read (each once: a file read twice with
    other contents is recorded twice). Pass it explicitly to the readers."""

    records: list[FileRecord] = field(default_factory=list)

    def add(self, path: str | os.PathLike, data: bytes) -> FileRecord:
        """Record ``data`` as the contents of ``path``."""
        rec = FileRecord(str(Path(path).absolute()), len(data), hashlib.sha256(data).hexdigest())
        self.add_record(rec)
        return rec

    def add_record(self, rec: FileRecord) -> None:
        """Record ``rec`` (unless the same contents of the same path are already in)."""
        if rec not in self.records:
            self.records.append(rec)

    def digests(self) -> dict[str, str]:
        """``{path: sha256}`` of every file read."""
        return {r.path: r.sha256 for r in self.records}


_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def open_regular(path: str | os.PathLike, what: str | None = None) -> io.BufferedReader:
    """``path`` opened for reading if it is a regular file (links followed); never blocks
    on the open (``O_NONBLOCK``: a FIFO with no writer). :class:`UntrustedFileError`
    otherwise; ``what`` names the field in the message."""
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise UntrustedFileError(path, "no such file", what, missing=True) from None
    except OSError as err:
        raise UntrustedFileError(path, f"cannot be opened ({err.strerror or err})", what) from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = next((name for test, name in _KINDS if test(mode)), "not a file")
            raise UntrustedFileError(path, f"not a regular file ({kind}): refused", what, kind=kind)
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _read_capped(
    fh: io.BufferedReader, path: str | os.PathLike, cap: int, what: str | None
) -> bytes:
    size = os.fstat(fh.fileno()).st_size
    if size > cap:
        raise UntrustedFileError(path, f"{size} bytes; at most {cap}", what)
    try:
        data = fh.read(cap + 1)
    except OSError as err:
        raise UntrustedFileError(path, f"cannot be read ({err.strerror or err})", what) from None
    if len(data) > cap:
        raise UntrustedFileError(path, f"grew past {cap} bytes while read", what)
    return data


def read_bytes(
    path: str | os.PathLike, cap: int, what: str | None = None, log: ReadLog | None = None
) -> bytes:
    """The contents of the regular file ``path``, at most ``cap`` bytes (its size checked
    before it is read); recorded in ``log`` when given."""
    with open_regular(path, what) as fh:
        data = _read_capped(fh, path, cap, what)
    if log is not None:
        log.add(path, data)
    return data


def hash_file(path: str | os.PathLike, what: str | None = None) -> FileRecord:
    """The SHA-256 of the regular file ``path``, read in 1 MiB pieces (any size: nothing
    is kept)."""
    digest, size = hashlib.sha256(), 0
    with open_regular(path, what) as fh:
        try:
            while piece := fh.read(1 << 20):
                digest.update(piece)
                size += len(piece)
        except OSError as err:
            raise UntrustedFileError(
                path, f"cannot be read ({err.strerror or err})", what
            ) from None
    return FileRecord(str(Path(path).absolute()), size, digest.hexdigest())


def json_nesting(text: str, quotes: str = '"') -> int:
    """How deep lists and objects nest in JSON ``text``, counted on the text (strings in
    ``quotes`` skipped; ``"'`` for a Python literal), so that a document too deep is
    refused before it is parsed.

    >>> json_nesting('{"a": [1, {"b": "[[["}]}'), json_nesting("3")
    (3, 0)
    """
    deepest = depth = 0
    i, n = 0, len(text)
    while i < n:
        j = min((k for k in (text.find(c, i) for c in quotes + "[{(]})") if k >= 0), default=n)
        if j >= n:
            break
        c = text[j]
        if c in quotes:  # skip the string, escapes included
            k = j + 1
            while True:
                k = text.find(c, k)
                if k < 0:
                    return deepest
                back = k - 1
                while text[back] == "\\":
                    back -= 1
                if (k - 1 - back) % 2 == 0:
                    break
                k += 1
            i = k + 1
            continue
        depth += 1 if c in "[{(" else -1
        deepest = max(deepest, depth)
        i = j + 1
    return deepest


def parse_json(text: str, where: str | os.PathLike, limits: FileLimits = LIMITS) -> Any:
    """JSON ``text`` parsed, nested at most ``limits.json_depth`` deep (checked first);
    :class:`UntrustedFileError` naming ``where`` otherwise."""
    depth = json_nesting(text)
    if depth > limits.json_depth:
        raise UntrustedFileError(where, f"JSON nested {depth} deep; at most {limits.json_depth}")
    try:
        return json.loads(text, object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as err:
        raise UntrustedFileError(where, f"not valid JSON, cut short or damaged ({err})") from None
    except _DuplicateKey as err:
        raise UntrustedFileError(where, f"the key {err.args[0]!r} is given twice") from None


class _DuplicateKey(Exception):
    """A JSON object names a key twice (``json`` would keep the last silently)."""


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def read_json(
    path: str | os.PathLike, limits: FileLimits = LIMITS, log: ReadLog | None = None
) -> Any:
    """The JSON document in ``path``: a regular file of at most ``limits.json_bytes`` of
    UTF-8 text nested at most ``limits.json_depth`` deep."""
    data = read_bytes(path, limits.json_bytes, log=log)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise UntrustedFileError(
            path, f"not UTF-8 text ({err.reason} at byte {err.start})"
        ) from None
    return parse_json(text, path, limits)


# ----------------------------------------------------------------------------------------
# Archives


def npz_members(
    path: str | os.PathLike, limits: FileLimits = LIMITS, log: ReadLog | None = None
) -> dict[str, bytes]:
    """The members of the ``.npz`` (zip) archive ``path``, inflated: the archive at most
    ``limits.npz_bytes``, its members' declared sizes together at most
    ``limits.npz_inflated_bytes`` (checked before any is inflated); no member inflates
    past its declared size (a forged size fails its CRC check there)."""
    with open_regular(path) as fh:
        data = _read_capped(fh, path, limits.npz_bytes, None)
    if log is not None:
        log.add(path, data)
    import zipfile

    cap = limits.npz_inflated_bytes
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            infos = zf.infolist()
            declared = sum(i.file_size for i in infos)
            if declared > cap:
                raise UntrustedFileError(
                    path, f"its members inflate to {declared} bytes; at most {cap}"
                )
            out: dict[str, bytes] = {}
            for info in infos:  # zipfile stops at the declared size and checks the CRC
                with zf.open(info) as member:
                    out[info.filename] = member.read(info.file_size)
            return out
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError) as err:
        if isinstance(err, UntrustedFileError):
            raise
        raise UntrustedFileError(path, f"not a readable .npz archive ({err})") from None


def npy_array(path: str | os.PathLike, name: str, body: bytes) -> np.ndarray:
    """One ``.npy`` member (no pickled objects); :class:`UntrustedFileError` otherwise."""
    import numpy as np  # here: the report reads JSON without it

    try:
        return np.load(io.BytesIO(body), allow_pickle=False)
    except (ValueError, OSError, EOFError) as err:
        raise UntrustedFileError(path, f"not a readable array ({err})", name) from None


def read_npz(
    path: str | os.PathLike, limits: FileLimits = LIMITS, log: ReadLog | None = None
) -> dict[str, np.ndarray]:
    """The arrays of the ``.npz`` archive ``path`` (:func:`npz_members`'s caps; no pickled
    objects), by name (``.npy`` dropped)."""
    return {
        name.removesuffix(".npy"): npy_array(path, name, body)
        for name, body in npz_members(path, limits, log).items()
    }


# ----------------------------------------------------------------------------------------
# Textures

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}


def png_size(
    data: bytes, where: str | os.PathLike, what: str | None = None
) -> tuple[int, int, int]:
    """(width, height, bytes a pixel decoded) from a PNG's IHDR, before it is decoded.

    >>> import zlib
    >>> ihdr = struct.pack(">IIBBBBB", 3, 2, 8, 6, 0, 0, 0)
    >>> png = _PNG_MAGIC + struct.pack(">I", 13) + b"IHDR" + ihdr + b"crc!"
    >>> png_size(png, "t.png")
    (3, 2, 4)
    """
    if not data.startswith(_PNG_MAGIC) or len(data) < 33 or data[12:16] != b"IHDR":
        raise UntrustedFileError(where, "not a PNG file (textures are read as PNG)", what)
    width, height, depth, colour = struct.unpack(">IIBB", data[16:26])
    if colour not in _PNG_CHANNELS or depth not in (1, 2, 4, 8, 16):
        raise UntrustedFileError(where, f"PNG colour type {colour}, depth {depth}: damaged", what)
    return width, height, max(1, _PNG_CHANNELS[colour] * depth // 8)


def check_png(
    data: bytes, where: str | os.PathLike, max_pixels: int, what: str | None = None
) -> None:
    """A PNG of at most ``max_pixels`` (decoded), read from its IHDR."""
    width, height, _ = png_size(data, where, what)
    if width * height > max_pixels:
        raise UntrustedFileError(
            where,
            f"a {width} x {height} PNG ({width * height} pixels); at most {max_pixels}",
            what,
        )


# ----------------------------------------------------------------------------------------
# MJCF


class MJCFFiles(NamedTuple):
    """An MJCF file and everything it names, read and checked: MuJoCo compiles it from
    these bytes alone (:meth:`spec`), never from the file system."""

    path: str
    xml: str
    includes: dict[str, bytes]
    assets: dict[str, bytes]
    records: tuple[FileRecord, ...]

    def spec(self, prefix: str = "") -> mujoco.MjSpec:
        """The ``mujoco.MjSpec`` of these bytes (ValueError when MuJoCo refuses them); with
        a ``prefix``, the files its assets name are renamed ``prefix + name`` (the names
        :meth:`prefixed_assets` gives their bytes), for attaching it to another spec."""
        import mujoco

        spec = mujoco.MjSpec.from_string(self.xml, include=self.includes, assets=self.assets)
        if prefix:
            folders = {"textures": spec.texturedir}
            for kind in ("meshes", "textures", "hfields", "skins"):
                folder = folders.get(kind, spec.meshdir)
                for asset in getattr(spec, kind):
                    if asset.file:
                        asset.file = prefix + _combine(folder, asset.file)
            spec.meshdir = spec.texturedir = ""
        return spec

    def prefixed_assets(self, prefix: str) -> dict[str, bytes]:
        """The assets' bytes by the names :meth:`spec` gives them with ``prefix``."""
        return {prefix + name: data for name, data in self.assets.items()}


def _combine(folder: str, file: str) -> str:
    """The name MuJoCo gives a file in ``folder`` (its ``mjuu_combinePaths``)."""
    if not folder or os.path.isabs(file):
        return file
    return folder + ("" if folder.endswith(("/", "\\")) else "/") + file


def _count(value: str | None, what: str, path: str) -> int:
    """The product of the whitespace-separated integers of attribute ``what``."""
    total = 1
    for word in (value or "").split():
        try:
            n = int(word)
        except ValueError:
            raise UntrustedFileError(path, f"not an integer: {word[:40]!r}", what) from None
        total *= max(n, 0)
    return total


@dataclass
class _MJCFScan:
    main: Path
    limits: FileLimits
    log: ReadLog
    includes: dict[str, bytes] = field(default_factory=dict)
    texturedir: str = ""
    meshdir: str = ""
    bytes_read: int = 0
    files: int = 0
    elements: int = 0
    trees: list[ET.Element] = field(default_factory=list)

    def read(self, name: str, cap: int, what: str) -> bytes:
        """A file the MJCF names (relative: to the main file's folder), within the caps."""
        self.files += 1
        if self.files > self.limits.mjcf_files:
            raise UntrustedFileError(
                self.main, f"names more than {self.limits.mjcf_files} files", what
            )
        path = Path(name) if os.path.isabs(name) else self.main.parent / name
        return read_bytes(path, cap, f"{what} {name[:200]!r}", self.log)

    def parse(self, name: str, data: bytes, where: str) -> ET.Element:
        import xml.etree.ElementTree as ET

        self.bytes_read += len(data)
        if self.bytes_read > self.limits.mjcf_bytes:
            raise UntrustedFileError(
                where, f"the MJCF files together exceed {self.limits.mjcf_bytes} bytes"
            )
        if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
            raise UntrustedFileError(where, "a DOCTYPE or ENTITY declaration: refused")
        try:
            return ET.fromstring(data)
        except ET.ParseError as err:
            raise UntrustedFileError(where, f"not well-formed XML ({err})") from None

    def walk(self, root: ET.Element, where: str, depth: int, mult: int) -> None:
        """Count ``root``'s elements (replicates multiplied out) and read what they name."""
        stack: list[tuple[ET.Element, int]] = [(root, mult)]
        while stack:
            el, m = stack.pop()
            self.elements += m
            if self.elements > self.limits.mjcf_elements:
                raise UntrustedFileError(
                    where,
                    f"expands to more than {self.limits.mjcf_elements} elements",
                )
            tag = el.tag
            if tag == "replicate":
                m *= _count(el.get("count"), "replicate count", where)
                if m > self.limits.replicate_product:
                    raise UntrustedFileError(
                        where,
                        f"nested <replicate> counts multiply to {m}; at most "
                        f"{self.limits.replicate_product}",
                        "replicate count",
                    )
            elif tag in ("flexcomp", "composite"):
                n = m * _count(el.get("count"), f"{tag} count", where)
                if n > self.limits.replicate_product:
                    raise UntrustedFileError(
                        where,
                        f"{n} elements; at most {self.limits.replicate_product}",
                        f"{tag} count",
                    )
            elif tag == "compiler":
                self.texturedir = el.get("texturedir", el.get("assetdir", self.texturedir))
                self.meshdir = el.get("meshdir", el.get("assetdir", self.meshdir))
            elif tag == "model":
                raise UntrustedFileError(where, "<model> assets are not read (use <include>)")
            self.check_sizes(el, where)
            if tag == "include":
                self.include(el.get("file", ""), where, depth + 1, m)
            stack.extend((child, m) for child in reversed(list(el)))

    def check_sizes(self, el: ET.Element, where: str) -> None:
        lim = self.limits
        if el.tag == "texture" and ("width" in el.attrib or "height" in el.attrib):
            w = _count(el.get("width"), "texture width", where)
            h = _count(el.get("height", el.get("width")), "texture height", where)
            faces = 6 if el.get("type") in ("cube", "skybox") else 1
            if w * h * faces > lim.texture_pixels:
                raise UntrustedFileError(
                    where,
                    f"{w} x {h} x {faces} pixels; at most {lim.texture_pixels}",
                    "texture width",
                )
        if el.tag == "hfield" and ("nrow" in el.attrib or "ncol" in el.attrib):
            cells = _count(el.get("nrow"), "hfield nrow", where) * _count(
                el.get("ncol"), "hfield ncol", where
            )
            if cells > lim.hfield_cells:
                raise UntrustedFileError(
                    where, f"{cells} cells; at most {lim.hfield_cells}", "hfield nrow"
                )

    def include(self, name: str, where: str, depth: int, mult: int) -> None:
        if depth > self.limits.include_depth:
            raise UntrustedFileError(
                where, f"includes nested deeper than {self.limits.include_depth}"
            )
        data = self.read(name, self.limits.mjcf_bytes, "include file")
        self.includes[name] = data
        sub = str(self.main.parent / name)
        tree = self.parse(name, data, sub)
        self.trees.append(tree)
        self.walk(tree, sub, depth, mult)

    def assets(self) -> dict[str, bytes]:
        """Read every file the documents name (``file*`` attributes of all elements but
        ``<include>``), after the compiler's folders are known."""
        out: dict[str, bytes] = {}
        lim = self.limits
        for tree in self.trees:
            for el in tree.iter():
                if el.tag == "include":
                    continue
                for attr, file in el.attrib.items():
                    if not attr.startswith("file") or not file:
                        continue
                    is_texture = el.tag == "texture"
                    name = _combine(self.texturedir if is_texture else self.meshdir, file)
                    if name in out:
                        continue
                    what = f"{el.tag} {attr}"
                    if is_texture or (el.tag == "hfield" and name.lower().endswith(".png")):
                        data = self.read(name, lim.texture_bytes, what)
                        cap = lim.texture_pixels if is_texture else lim.hfield_cells
                        check_png(data, self.main.parent / name, cap, what)
                    else:
                        data = self.read(name, lim.mesh_bytes, what)
                    out[name] = data
        return out


def load_mjcf(
    path: str | os.PathLike, limits: FileLimits = LIMITS, log: ReadLog | None = None
) -> MJCFFiles:
    """The MJCF file ``path`` and every file it names, read through this module and
    checked (see the module docstring) before MuJoCo sees any of it."""
    main = Path(path)
    scan = _MJCFScan(main, limits, log if log is not None else ReadLog())
    first = len(scan.log.records)
    data = read_bytes(main, limits.mjcf_bytes, log=scan.log)
    root = scan.parse(str(main), data, str(main))
    if root.tag != "mujoco":
        raise UntrustedFileError(main, f"the root element is <{root.tag[:40]}>, not <mujoco>")
    scan.trees.insert(0, root)
    scan.walk(root, str(main), 0, 1)
    assets = scan.assets()
    return MJCFFiles(
        str(main),
        data.decode("utf-8", errors="replace"),
        scan.includes,
        assets,
        tuple(scan.log.records[first:]),
    )


def _model_sizes(model: mujoco.MjModel, lim: FileLimits) -> Iterator[tuple[str, int, int]]:
    yield "nbody", int(model.nbody), lim.model_bodies
    yield "ngeom", int(model.ngeom), lim.model_geoms
    yield "nmeshvert", int(model.nmeshvert), lim.model_vertices
    yield "nflexvert", int(model.nflexvert), lim.model_vertices
    yield "ntexdata", int(model.ntexdata), lim.model_texture_bytes
    yield "nhfielddata", int(model.nhfielddata), lim.hfield_cells


def check_model_size(
    model: mujoco.MjModel, where: str | os.PathLike, limits: FileLimits = LIMITS
) -> None:
    """The compiled ``model`` within ``limits`` (bodies, geoms, vertices, texture
    bytes, height-field cells); :class:`UntrustedFileError` naming the count otherwise."""
    for name, value, cap in _model_sizes(model, limits):
        if value > cap:
            raise UntrustedFileError(where, f"the model has {value}; at most {cap}", name)
