"""Every file read is bounded, nested ones too (wander_env.untrusted): regular files only,
sizes before reading, inflated sizes before inflating, MJCF expansions before compiling;
through the CLI each case is one line, exit 2 and a resident peak under 1 GB."""

from __future__ import annotations

import io
import json
import os
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml
from limited import GIB, run_limited
from locations import ROOT
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
    assert str(info.value) == f"{big}: {LIMITS.json_bytes + 1} bytes; at most {LIMITS.json_bytes}"
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
    assert str(info.value) == f"{path}: JSON nested 100000 deep; at most 64"
    assert json_nesting('["[[[", {"a": "\\"[["}]') == 2


def test_a_json_key_given_twice_is_refused_not_the_last_one_kept(tmp_path):
    path = tmp_path / "run.json"
    path.write_text('{"seed": 1, "config": {"a": 1, "a": 2}}')
    with pytest.raises(UntrustedFileError) as info:
        read_json(path)
    assert str(info.value) == f"{path}: the key 'a' is given twice"
    path.write_text('{"seed": 1, "config": {"a": 1, "b": [{"a": 2}]}}')
    assert read_json(path) == {"seed": 1, "config": {"a": 1, "b": [{"a": 2}]}}


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
        f"{bomb}: its members inflate to {declared} bytes; at most {LIMITS.npz_inflated_bytes}"
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
        "at most 16000000"
    )


@pytest.mark.parametrize(
    ("xml", "problem"),
    [
        (
            REPLICATE_BOMB,
            "replicate count: nested <replicate> counts multiply to 1000000; at most 10000",
        ),
        (
            '<mujoco><asset><texture name="t" builtin="checker" width="100000" '
            'height="100000"/></asset></mujoco>',
            "texture width: 100000 x 100000 x 1 pixels; at most 16777216",
        ),
        ('<mujoco><include file="x.xml"/></mujoco>', "includes nested deeper than 8"),
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
            f"(1600000000 pixels); at most {LIMITS.texture_pixels}"
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
            "1000000; at most 10000"
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


# ----------------------------------------------------------------------------------------
# Archives, results and trial files through the CLI


def _npy(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return buf.getvalue()


def npz_bomb(path: Path, bomb: str, mib: int = 600, **members: np.ndarray) -> Path:
    """An .npz whose member ``bomb`` is ``mib`` MiB of zeros (written in pieces: the test
    never holds it), beside small ``members``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, arr in members.items():
            zf.writestr(f"{name}.npy", _npy(arr))
        with zf.open(f"{bomb}.npy", "w", force_zip64=True) as fh:
            header = {"descr": "|u1", "fortran_order": False, "shape": (mib << 20,)}
            np.lib.format.write_array_header_1_0(fh, header)
            piece = bytes(16 << 20)
            for _ in range(mib // 16):
                fh.write(piece)
    return path


def declared(path: Path) -> int:
    """What the members of the zip ``path`` declare they inflate to."""
    with zipfile.ZipFile(path) as zf:
        return sum(i.file_size for i in zf.infolist())


EVIMO_META = json.dumps({"frames": [{"ts": 0.05, "id": 0}], "meta": {"res_x": 4, "res_y": 3}})


@pytest.mark.slow
def test_a_zip_bombed_evimo_npz_is_one_line_within_1_gb(tmp_path):
    seq = npz_bomb(
        tmp_path / "evimo" / "box" / "seq_00.npz",
        "mask",
        events=np.zeros((5, 4)),
        meta=np.asarray(EVIMO_META),
    )
    assert seq.stat().st_size < 1 << 20 and declared(seq) > 600_000_000
    args = ["benchmark", "evimo", "evimo", "--no-progress", "--out", "out"]
    rc, err, peak = run_limited(args, tmp_path)
    assert (rc, err) == (
        2,
        [
            "wander benchmark evimo: error: evimo/box/seq_00.npz: its members inflate to "
            f"{declared(seq)} bytes; at most {LIMITS.npz_inflated_bytes}"
        ],
    )
    assert 0 < peak < GIB


@pytest.mark.slow
def test_evimo_metadata_nested_100000_deep_is_one_line(tmp_path):
    seq = tmp_path / "evimo" / "box" / "seq_00.npz"
    seq.parent.mkdir(parents=True)
    deep = '{"frames": ' + "[" * 100_000 + "]" * 100_000 + "}"
    np.savez_compressed(
        seq, events=np.zeros((5, 4)), mask=np.zeros((1, 3, 4)), meta=np.asarray(deep)
    )
    rc, err, peak = run_limited(["benchmark", "evimo", "evimo", "--no-progress"], tmp_path)
    assert (rc, err) == (
        2,
        [
            "wander benchmark evimo: error: evimo/box/seq_00.npz: "
            "'meta' nested 100001 deep; at most 64"
        ],
    )
    assert 0 < peak < GIB


def _result_folder(root: Path) -> Path:
    from test_report import _scanpath_folder

    return _scanpath_folder(root / "results")


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["/dev/zero", "fifo"])
def test_a_config_json_that_is_not_a_file_is_one_line_not_a_hang(tmp_path, kind):
    config = _result_folder(tmp_path) / "config.json"
    config.unlink()
    if kind == "fifo":
        os.mkfifo(config)
    else:
        config.symlink_to(kind)
    rc, err, peak = run_limited(["report", "--results", "results", "--out", "R.md"], tmp_path)
    what = "a FIFO" if kind == "fifo" else "a character device"
    assert (rc, err) == (
        2,
        [
            "wander report: error: results/scanpath/x/config.json: not a regular file "
            f"({what}): refused"
        ],
    )
    assert 0 < peak < GIB and not (tmp_path / "R.md").exists()


@pytest.mark.slow
def test_a_zip_bombed_scanpath_artifact_is_one_line_within_1_gb(tmp_path):
    folder = _result_folder(tmp_path)
    bomb = npz_bomb(folder / "artifacts" / "t0.npz", "gaze")
    rc, err, peak = run_limited(["report", "--results", "results", "--out", "R.md"], tmp_path)
    assert (rc, err) == (
        2,
        [
            "wander report: error: results/scanpath/x/results.csv: scanpath's figures failed on "
            "its rows (UntrustedFileError: results/scanpath/x/artifacts/t0.npz: its members "
            f"inflate to {declared(bomb)} bytes; at most {LIMITS.npz_inflated_bytes})"
        ],
    )
    assert 0 < peak < GIB


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["/dev/zero", "fifo"])
def test_a_trial_file_that_is_not_a_file_is_set_aside_on_resume(tmp_path, kind):
    from test_sweep import TOY_SWEEP, CountingRunner

    from experiments.studies.sweep import run_sweep, sweep_from_dict

    sweep = sweep_from_dict(TOY_SWEEP)
    runner = CountingRunner()
    first = run_sweep(sweep, tmp_path, backend="serial", runner=runner)
    victim = first.rows[4]["trial_id"]
    path = tmp_path / "trials" / f"{victim}.json"
    path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to(kind)
    runner.calls.clear()
    with pytest.warns(RuntimeWarning) as warned:
        res = run_sweep(sweep, tmp_path, backend="serial", runner=runner)
    what = "a FIFO" if kind == "fifo" else "a character device"
    assert [str(w.message) for w in warned] == [
        f"{path}: damaged trial file (not a regular file ({what}): refused); set aside as "
        f"{victim}.json.corrupt, the trial is rerun"
    ]
    assert len(runner.calls) == 1 and [r["trial_id"] for r in res.rows] == [
        r["trial_id"] for r in first.rows
    ]


def test_the_docs_list_every_cap_with_its_value_and_reason():
    from wander_env.untrusted import limits_table

    page = (ROOT / "docs" / "limits.md").read_text(encoding="utf-8")
    assert limits_table() in page


def test_a_compiled_model_over_its_size_is_refused(tmp_path):
    from wander_env.untrusted import check_model_size

    path = tmp_path / "boxes.xml"
    path.write_text(
        '<mujoco><worldbody><replicate count="30"><geom type="box" size=".1 .1 .1"/>'
        "</replicate></worldbody></mujoco>"
    )
    model = load_mjcf(path).spec().compile()
    check_model_size(model, path)  # within the default caps
    with pytest.raises(UntrustedFileError) as info:
        check_model_size(model, path, FileLimits(model_geoms=20))
    assert str(info.value) == f"{path}: ngeom: the model has 30; at most 20"


def test_an_included_files_textures_are_attached_under_its_prefix(tmp_path):
    from PIL import Image

    (tmp_path / "tex").mkdir()
    for side in ("right", "left", "up", "down", "front", "back"):
        Image.new("RGB", (8, 8), (200, 10, 10)).save(tmp_path / "tex" / f"{side}.png")
    Image.new("RGB", (8, 8), (10, 200, 10)).save(tmp_path / "tex" / "flat.png")
    faces = " ".join(f'file{s}="{s}.png"' for s in ("right", "left", "up", "down", "front", "back"))
    (tmp_path / "box.xml").write_text(
        f'<mujoco><compiler texturedir="tex"/><asset><texture name="c" type="cube" {faces}/>'
        '<texture name="f" type="2d" file="flat.png"/>'
        '<material name="m" texture="c"/><material name="n" texture="f"/></asset>'
        '<worldbody><body name="b"><geom type="box" size=".1 .1 .1" material="m"/>'
        '<geom type="box" pos="0 0 1" size=".1 .1 .1" material="n"/></body></worldbody>'
        "</mujoco>"
    )
    from wander_env.mjcf import compile_scene
    from wander_env.scenes import scene_config_from_dict

    cfg = scene_config_from_dict({"mjcf_includes": [{"file": str(tmp_path / "box.xml")}]})
    assert [Path(r.path).name for r in cfg.files_read()] == [
        "box.xml",
        "right.png",
        "left.png",
        "up.png",
        "down.png",
        "front.png",
        "back.png",
        "flat.png",
    ]
    model = compile_scene(cfg)
    assert model.texture("include_0/c").id >= 0 and model.texture("include_0/f").id >= 0


def test_a_config_file_that_is_a_fifo_is_one_line_not_a_hang(tmp_path):
    from wander_env.config import ConfigError, load_yaml

    os.mkfifo(tmp_path / "sweep.yaml")
    with pytest.raises(ConfigError) as info:
        load_yaml(tmp_path / "sweep.yaml", "sweep file")
    assert str(info.value) == (
        f"{tmp_path / 'sweep.yaml'}: the sweep file: not a regular file (a FIFO): refused"
    )
