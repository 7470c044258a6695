"""Every file read is bounded, nested ones too (wander_env.untrusted): regular files only,
sizes before reading, inflated sizes before inflating, MJCF expansions before compiling;
through the CLI each case is one line, exit 2 and a resident peak under 1 GB."""

from __future__ import annotations

import io
import os
import struct
import subprocess
import sys
import textwrap
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml
from scene_files import write_arm

from wander_env.untrusted import (
    LIMITS,
    FileLimits,
    ReadLog,
    UntrustedFileError,
    json_nesting,
    load_mjcf,
    read_bytes,
    read_json,
    read_npz,
)

ROOT = Path(__file__).resolve().parents[1]
GIB = 1 << 30

# The CLI under an address-space limit, printing its own resident peak (VmHWM) at exit.
LIMITED = textwrap.dedent(
    """
    import resource, sys
    limit = int(sys.argv[1])
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    sys.argv = ["wander", *sys.argv[2:]]
    from experiments.cli.main import main
    try:
        main()
    finally:
        with open("/proc/self/status") as f:
            peak_kib = next(int(w.split()[1]) for w in f if w.startswith("VmHWM:"))
        print(f"peak {peak_kib}", file=sys.stdout, flush=True)
    """
)


def run_limited(args: list[str], cwd: Path, limit: int = 2 * GIB) -> tuple[int, list[str], int]:
    """(exit status, stderr lines, resident peak in bytes) of ``wander ARGS`` in ``cwd``;
    a hang fails the test (the timeout)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl"}
    proc = subprocess.run(
        [sys.executable, "-c", LIMITED, str(limit), *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=cwd,
        env=env,
    )
    peaks = [int(w.split()[1]) for w in proc.stdout.splitlines() if w.startswith("peak ")]
    return proc.returncode, proc.stderr.splitlines(), peaks[0] * 1024 if peaks else -1


def png_bomb(path: Path, side: int = 40_000) -> Path:
    """A valid grey PNG of side x side zero pixels (1.6 GB decoded, ~1.6 MB stored): one
    deflate block of 100 rows, flushed so it stands alone, repeated."""
    rows = 100
    raw = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = raw.compress(bytes((side + 1) * rows)) + raw.flush(zlib.Z_FULL_FLUSH)
    total = (side + 1) * side  # every byte zero: Adler-32 is (n mod 65521) << 16 | 1
    stream = (
        b"\x78\xda"
        + block * (side // rows)
        + b"\x03\x00"
        + struct.pack(">I", (total % 65521) << 16 | 1)
    )

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (
            struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
        )

    ihdr = struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", stream) + chunk(b"IEND", b"")
    path.write_bytes(png)
    return path


REPLICATE_BOMB = (
    '<mujoco><worldbody><replicate count="1000"><replicate count="1000">'
    '<replicate count="1000"><geom size=".1"/></replicate></replicate></replicate>'
    "</worldbody></mujoco>"
)


def scene_with_include(folder: Path, include: str) -> Path:
    scene = folder / "scene.yaml"
    scene.write_text(yaml.safe_dump({"mjcf_includes": [{"file": include}]}))
    return scene


# ----------------------------------------------------------------------------------------
# The reader


def test_only_regular_files_are_read_and_a_fifo_never_blocks(tmp_path):
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    (tmp_path / "zero.json").symlink_to("/dev/zero")
    with pytest.raises(UntrustedFileError) as info:
        read_json(fifo)  # no writer: a blocking open would hang here
    assert str(info.value) == f"{fifo}: not a regular file (a FIFO): refused"
    with pytest.raises(UntrustedFileError) as info:
        read_json(tmp_path / "zero.json")
    assert (
        str(info.value)
        == f"{tmp_path / 'zero.json'}: not a regular file (a character device): refused"
    )
    with pytest.raises(UntrustedFileError) as info:
        read_json(tmp_path)
    assert str(info.value) == f"{tmp_path}: not a regular file (a folder): refused"


def test_a_file_over_its_cap_is_refused_unread_and_a_read_is_logged(tmp_path):
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(LIMITS.json_bytes + 1)  # sparse: reading it would take 8 MiB
    with pytest.raises(UntrustedFileError) as info:
        read_json(big)
    assert (
        str(info.value)
        == f"{big}: {LIMITS.json_bytes + 1} bytes; at most {LIMITS.json_bytes} (the limit)"
    )
    (tmp_path / "a.bin").write_bytes(b"abc")
    log = ReadLog()
    assert read_bytes(tmp_path / "a.bin", 3, log=log) == b"abc"
    assert log.digests() == {
        str(tmp_path / "a.bin"): "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    }


def test_json_nested_100000_deep_is_one_line(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(UntrustedFileError) as info:
        read_json(path)
    assert str(info.value) == f"{path}: JSON nested 100000 deep; at most 64 (the limit)"
    assert json_nesting('["[[[", {"a": "\\"[["}]') == 2


def _npz(members: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **members)
    return buf.getvalue()


def test_a_zip_bombed_npz_is_refused_before_it_inflates(tmp_path):
    bomb = tmp_path / "bomb.npz"
    bomb.write_bytes(_npz({"events": np.zeros(600 * 2**20, np.uint8)}))  # 600 MiB of zeros
    assert bomb.stat().st_size < 1 << 20
    declared = 600 * 2**20 + 128  # the .npy header
    with pytest.raises(UntrustedFileError) as info:
        read_npz(bomb)
    assert str(info.value) == (
        f"{bomb}: its members inflate to {declared} bytes; at most {LIMITS.npz_inflated_bytes} "
        "(the limit)"
    )


def test_an_npz_member_forged_to_declare_less_than_it_inflates_to_is_caught(tmp_path):
    body = _npz({"a": np.zeros(4096, np.uint8)})
    # rewrite the member's declared size (local header and central directory) to 100 bytes
    with zipfile.ZipFile(io.BytesIO(body)) as zf:
        real = zf.infolist()[0].file_size
    forged = body.replace(struct.pack("<I", real), struct.pack("<I", 100))
    path = tmp_path / "forged.npz"
    path.write_bytes(forged)
    with pytest.raises(UntrustedFileError) as info:
        read_npz(path)
    # inflating stops at the declared 100 bytes, whose CRC then fails
    assert str(info.value) == f"{path}: not a readable .npz archive (Bad CRC-32 for file 'a.npy')"
    (tmp_path / "ok.npz").write_bytes(body)
    assert read_npz(tmp_path / "ok.npz")["a"].shape == (4096,)


# ----------------------------------------------------------------------------------------
# MJCF


def test_an_mjcf_and_every_file_it_names_are_read_through_the_reader(tmp_path):
    arm = write_arm(tmp_path)
    (tmp_path / "outer.xml").write_text('<mujoco><include file="arm.xml"/></mujoco>')
    log = ReadLog()
    files = load_mjcf(tmp_path / "outer.xml", log=log)
    assert [Path(r.path).name for r in log.records] == ["outer.xml", "arm.xml", "tetra.obj"]
    assert sorted(files.includes) == ["arm.xml"] and sorted(files.assets) == ["tetra.obj"]
    model = files.spec().compile()
    assert model.body("link").id > 0 and model.nmesh == 1
    assert arm.exists()


def test_a_png_bomb_texture_is_refused_from_its_header(tmp_path):
    png_bomb(tmp_path / "bomb.png", side=5000)
    (tmp_path / "tex.xml").write_text(
        '<mujoco><asset><texture name="t" type="2d" file="bomb.png"/></asset></mujoco>'
    )
    with pytest.raises(UntrustedFileError) as info:
        load_mjcf(tmp_path / "tex.xml", FileLimits(texture_pixels=4000 * 4000))
    assert str(info.value) == (
        f"{tmp_path / 'bomb.png'}: texture file: a 5000 x 5000 PNG (25000000 pixels); "
        "at most 16000000 (the limit)"
    )


@pytest.mark.parametrize(
    ("xml", "problem"),
    [
        (
            REPLICATE_BOMB,
            "replicate count: nested <replicate> counts multiply to 1000000; "
            "at most 10000 (the limit)",
        ),
        (
            '<mujoco><asset><texture name="t" builtin="checker" width="100000" '
            'height="100000"/></asset></mujoco>',
            "texture width: 100000 x 100000 x 1 pixels; at most 16777216 (the limit)",
        ),
        ('<mujoco><include file="x.xml"/></mujoco>', "includes nested deeper than 8 (the limit)"),
        (
            '<!DOCTYPE m [<!ENTITY a "aaaa">]><mujoco/>',
            "a DOCTYPE or ENTITY declaration: refused",
        ),
    ],
)
def test_mjcf_expansions_are_refused_before_compiling(tmp_path, xml, problem):
    path = tmp_path / "x.xml"
    path.write_text(xml)
    with pytest.raises(UntrustedFileError) as info:
        load_mjcf(path)
    assert str(info.value) == f"{path}: {problem}"


# ----------------------------------------------------------------------------------------
# Through the CLI: one line, exit 2, a bounded peak, no hang


@pytest.mark.slow
def test_a_png_bomb_inside_an_included_mjcf_is_one_line_within_1_gb(tmp_path):
    png_bomb(tmp_path / "bomb.png")
    assert 1_500_000 < (tmp_path / "bomb.png").stat().st_size < 1_700_000
    (tmp_path / "inner.xml").write_text(
        '<mujoco><asset><texture name="t" type="2d" file="bomb.png"/>'
        '<material name="m" texture="t"/></asset></mujoco>'
    )
    (tmp_path / "outer.xml").write_text('<mujoco><include file="inner.xml"/></mujoco>')
    scene_with_include(tmp_path, "outer.xml")
    rc, err, peak = run_limited(["run", "--scene", "scene.yaml", "--seconds", "0.01"], tmp_path)
    assert (rc, err) == (
        2,
        [
            "wander run: Invalid value for '--scene': scene.yaml: mjcf_includes[0].file: "
            f"{tmp_path / 'bomb.png'}: texture file: a 40000 x 40000 PNG "
            f"(1600000000 pixels); at most {LIMITS.texture_pixels} (the limit)"
        ],
    )
    assert 0 < peak < GIB


@pytest.mark.slow
def test_a_204_byte_nested_replicate_is_one_line_within_1_gb(tmp_path):
    (tmp_path / "rep.xml").write_text(REPLICATE_BOMB)
    assert len(REPLICATE_BOMB) <= 204
    scene_with_include(tmp_path, "rep.xml")
    rc, err, peak = run_limited(["run", "--scene", "scene.yaml", "--seconds", "0.01"], tmp_path)
    assert (rc, err) == (
        2,
        [
            "wander run: Invalid value for '--scene': scene.yaml: mjcf_includes[0].file: "
            f"{tmp_path / 'rep.xml'}: replicate count: nested <replicate> counts multiply to "
            "1000000; at most 10000 (the limit)"
        ],
    )
    assert 0 < peak < GIB


@pytest.mark.slow
def test_a_fifo_named_by_an_mjcf_include_is_one_line_not_a_hang(tmp_path):
    os.mkfifo(tmp_path / "pipe.xml")
    (tmp_path / "outer.xml").write_text('<mujoco><include file="pipe.xml"/></mujoco>')
    scene_with_include(tmp_path, "outer.xml")
    rc, err, _ = run_limited(["run", "--scene", "scene.yaml", "--seconds", "0.01"], tmp_path)
    assert (rc, err) == (
        2,
        [
            "wander run: Invalid value for '--scene': scene.yaml: mjcf_includes[0].file: "
            f"{tmp_path / 'pipe.xml'}: include file 'pipe.xml': not a regular file (a FIFO): "
            "refused"
        ],
    )
