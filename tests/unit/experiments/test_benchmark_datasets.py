"""Tests for the benchmark dataset loaders (experiments.benchmark.datasets).

Every loader is run on small synthetic files written here in the documented formats
(EVIMO1 NPZ, EVIMO2v2 NPZ folders, LLE-VOS folders, NNNNNN_T.png mask folders), and the
mask-folder reader on the real ``../shared/realdata`` masks when they are present.
"""

from __future__ import annotations

import json
import zipfile
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from locations import REALDATA
from PIL import Image

from experiments.benchmark.datasets import (
    DatasetLayoutError,
    MaskWindow,
    find_evimo_sequences,
    fit_mask,
    load_evimo,
    load_generic,
    load_llevos,
    mask_fit,
    read_mask_folder,
)
from experiments.benchmark.datasets.evimo import (
    mask_labels,
    read_npz_meta,
    windows_from_frame_times,
)
from experiments.benchmark.datasets.llevos import LLEVOSConfig
from experiments.benchmark.datasets.masks import parse_mask_name, read_mask_png
from wander_env.events import EVENT_DTYPE

needs_realdata = pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata absent")


# ----------------------------------------------------------------------------------------
# Writers for the synthetic files


def write_png_p(path: Path, values: np.ndarray) -> None:
    """A palette (mode P) PNG storing ``values`` as indices."""
    h, w = values.shape
    im = Image.new("P", (w, h))
    im.putdata(values.astype(np.uint8).ravel().tolist())
    im.putpalette([0, 0, 0, 255, 255, 255] + [128, 0, 0] * 254)
    path.parent.mkdir(parents=True, exist_ok=True)
    im.save(path)


def rect(shape, y0, y1, x0, x1, value=1, dtype=np.uint16):
    a = np.zeros(shape, dtype=dtype)
    a[y0:y1, x0:x1] = value
    return a


def evimo_meta(ts, w, h, ids=None):
    ids = list(range(len(ts))) if ids is None else ids
    frames = [
        {
            "ts": t,
            "id": i,
            "gt_frame": f"depth_mask_{i}.png",
            "cam": {"pos": {"t": {"x": 0.0, "y": 0.0, "z": 0.0}}, "ts": t},
        }
        for t, i in zip(ts, ids, strict=True)
    ]
    return {
        "frames": frames,
        "full_trajectory": [],
        "meta": {"res_x": w, "res_y": h, "fx": 200.0, "fy": 200.0, "cx": w / 2, "cy": h / 2},
    }


# EVIMO1 synthetic sequence: 20 x 16 sensor, masks at 0.05 s and 0.10 s.
W1, H1 = 20, 16
EV1 = np.array(
    [  # t [s], x, y, p — float32 as in the release
        [0.010, 1, 2, 1],
        [0.020, 19, 15, 0],
        [0.060, 5, 5, 1],
        [0.070, 6, 5, 1],
        [0.120, 0, 0, 0],
    ],
    dtype=np.float32,
)
MASK1 = np.stack(
    [
        rect((H1, W1), 2, 6, 3, 8, 1000),  # object 1, 4 x 5 = 20 px
        rect((H1, W1), 8, 10, 10, 13, 2000) + rect((H1, W1), 0, 1, 0, 4, 1000),  # 6 + 4 px
    ]
)


def write_evimo1(path: Path, meta=None, **overrides) -> Path:
    arrays = {
        "events": EV1,
        "index": np.array([0, 2, 4], dtype=np.uint32),
        "classical": None,
        "discretization": 0.01,
        "K": np.eye(3),
        "D": np.zeros(4),
        "depth": np.zeros_like(MASK1),
        "mask": MASK1,
        "meta": evimo_meta([0.05, 0.10], W1, H1) if meta is None else meta,
    }
    arrays.update(overrides)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)
    return path


def write_evimo2(folder: Path) -> Path:
    """EVIMO2v2 folder: 3 frames (ids 10, 11, 12), the mask of id 11 missing."""
    folder.mkdir(parents=True, exist_ok=True)
    t = np.array([0.001, 0.0015, 0.0031, 0.0042, 0.0099], dtype=np.float64)
    xy = np.array([[0, 0], [3, 4], [7, 5], [7, 5], [1, 1]], dtype=np.uint16)
    p = np.array([1, 0, 1, 1, 0], dtype=np.uint8)
    np.save(folder / "dataset_events_t.npy", t)
    np.save(folder / "dataset_events_xy.npy", xy)
    np.save(folder / "dataset_events_p.npy", p)
    masks = {
        "mask_0000000000": rect((6, 8), 0, 2, 0, 2, 1000),
        "mask_0000000002": rect((6, 8), 4, 6, 6, 8, 3000),
    }
    np.savez(folder / "dataset_mask.npz", **masks)
    np.savez(folder / "dataset_depth.npz", depth_0000000000=np.zeros((6, 8), np.uint16))
    meta = evimo_meta([0.002, 0.003, 0.004], 8, 6, ids=[10, 11, 12])
    np.savez(
        folder / "dataset_info.npz",
        meta=meta,
        K=np.eye(3),
        D=np.zeros(4),
        index=np.array([0], np.uint32),
        discretization=0.01,
    )
    return folder


# ----------------------------------------------------------------------------------------
# Mask folders


def test_parse_mask_name():
    assert parse_mask_name("000052_260000.png") == (52, 260000)
    assert parse_mask_name("15000.png") == (None, 15000)
    with pytest.raises(ValueError, match="not a mask name"):
        parse_mask_name("frame_a.png")


def test_read_mask_folder_synthetic(tmp_path):
    a = rect((6, 9), 1, 3, 2, 5, 1, np.uint8)  # 6 px
    write_png_p(tmp_path / "000001_5000.png", a)
    write_png_p(tmp_path / "000002_10000.png", np.zeros((6, 9), np.uint8))
    # 0/255 grey PNG, and a missing frame (15000): a gap, not a longer window
    Image.fromarray(rect((6, 9), 0, 1, 0, 9, 255, np.uint8)).save(tmp_path / "000004_20000.png")
    (tmp_path / "notes.txt").write_text("ignored")
    wins = read_mask_folder(tmp_path)
    assert [(w.t_start_us, w.t_end_us) for w in wins] == [(0, 5000), (5000, 10000), (15000, 20000)]
    assert [int(w.mask.sum()) for w in wins] == [6, 0, 9]
    t0, t1, m = wins[0]  # unpacks as (t_start, t_end, mask)
    assert (t0, t1, m.dtype, m.shape) == (0, 5000, np.bool_, (6, 9))
    assert np.array_equal(m, a > 0)
    assert wins[0].object_ids == (1,) and wins[2].object_ids == (255,)
    given = read_mask_folder(tmp_path, window_us=2000)
    assert (given[0].t_start_us, given[0].t_end_us) == (3000, 5000)


def test_read_mask_folder_errors_name_the_file(tmp_path):
    write_png_p(tmp_path / "000001_5000.png", np.zeros((6, 9), np.uint8))
    with pytest.raises(DatasetLayoutError, match="cannot infer the window"):
        read_mask_folder(tmp_path)
    write_png_p(tmp_path / "000002_10000.png", np.zeros((7, 9), np.uint8))
    with pytest.raises(DatasetLayoutError, match=r"000002_10000\.png.*7x9.*6x9"):
        read_mask_folder(tmp_path)
    (tmp_path / "000002_10000.png").write_bytes(b"\x89PNG not really")
    with pytest.raises(DatasetLayoutError, match=r"000002_10000\.png: unreadable mask"):
        read_mask_folder(tmp_path)
    (tmp_path / "000002_10000.png").unlink()
    write_png_p(tmp_path / "3_5000.png", np.zeros((6, 9), np.uint8))
    with pytest.raises(DatasetLayoutError, match="same end time T=5000"):
        read_mask_folder(tmp_path)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DatasetLayoutError, match=r"NNNNNN_T\.png"):
        read_mask_folder(empty)


def test_rgb_mask_gives_long_ids(tmp_path):
    rgb = np.zeros((3, 4, 3), np.uint8)
    rgb[0, 0] = (1, 0, 0)
    rgb[1, 1] = (0, 1, 0)
    Image.fromarray(rgb).save(tmp_path / "m.png")
    lab = read_mask_png(tmp_path / "m.png")
    assert lab[0, 0] == 1 and lab[1, 1] == 256 and lab.sum() == 257


@needs_realdata
def test_read_real_mask_folder():
    wins = read_mask_folder(REALDATA / "eed_ball_net" / "ref_masks_tt_adapt")
    assert len(wins) == 52
    assert {w.t_end_us - w.t_start_us for w in wins} == {5000}
    assert (wins[0].t_start_us, wins[0].t_end_us) == (0, 5000)
    assert wins[-1].t_end_us == 260000
    assert {w.shape for w in wins} == {(180, 190)}  # 190 x 180 (W x H)
    assert all(w.mask.dtype == np.bool_ for w in wins)
    assert {i for w in wins for i in w.object_ids} == {1}


@needs_realdata
def test_generic_loader_on_real_recording():
    root = REALDATA / "eed_ball_net"
    seq = load_generic(root / "events_txyp.npy", root / "ref_masks_tt_adapt")
    assert seq.sensor_size == (190, 180, 2)
    assert seq.n_events == 271264 and seq.events.dtype == EVENT_DTYPE
    assert len(seq.windows) == 52
    assert any("sensor size taken from the masks" in n for n in seq.notes)


# ----------------------------------------------------------------------------------------
# Fitting masks to the sensor grid


def test_mask_fit_identity_resize_and_pad():
    m = np.zeros((4, 5), bool)
    m[1, 2] = True
    same, fit = fit_mask(m, (5, 4, 2))
    assert fit.mode == "identity" and not fit.changed and same is m
    big, fit = fit_mask(m, (10, 8, 2))
    assert fit.mode == "resize_nearest" and (fit.scale_x, fit.scale_y) == (2.0, 2.0)
    assert np.argwhere(big).tolist() == [[2, 4], [2, 5], [3, 4], [3, 5]]
    assert "resized nearest-neighbour" in fit.describe()
    assert mask_fit((4, 5), (10, 4, 2)).aspect_changed
    placed, fit = fit_mask(m, (8, 6, 2), offset_xy=(3, 1))
    assert fit.mode == "pad" and placed.shape == (6, 8)
    assert np.argwhere(placed).tolist() == [[2, 5]]
    labels, _ = fit_mask(np.array([[0, 7], [3, 0]], np.uint8), (4, 4, 2))
    assert labels.dtype == np.uint8 and set(np.unique(labels)) == {0, 3, 7}


# ----------------------------------------------------------------------------------------
# EVIMO


def test_windows_from_frame_times_modes():
    ts = [100, 200, 300, 700]  # a ground-truth gap before 700
    assert windows_from_frame_times(ts) == [(0, 100), (100, 200), (200, 300), (600, 700)]
    assert windows_from_frame_times(ts, "following") == [
        (100, 200),
        (200, 300),
        (300, 400),
        (700, 800),
    ]
    assert windows_from_frame_times(ts, "centered") == [
        (50, 150),
        (150, 250),
        (250, 350),
        (650, 750),
    ]
    assert windows_from_frame_times([100, 105, 110], "centered", 5) == [
        (98, 103),
        (103, 108),
        (108, 113),
    ]
    assert windows_from_frame_times([100, 200], "preceding", 30) == [(70, 100), (170, 200)]
    with pytest.raises(ValueError, match="increase strictly"):
        windows_from_frame_times([100, 100])
    with pytest.raises(ValueError, match="not one of"):
        windows_from_frame_times([100, 200], "middle")


def test_mask_labels():
    assert mask_labels(np.array([[0, 1000, 2000, 999, 3]])).tolist() == [[0, 1, 2, 1, 1]]


def test_evimo1_npz_loader(tmp_path):
    write_evimo1(tmp_path / "box" / "seq_01.npz")
    (seq,) = list(load_evimo(tmp_path))
    assert (seq.dataset, seq.subset, seq.name) == ("evimo", "box", "seq_01")
    assert seq.sensor_size == (W1, H1, 2)
    ev = seq.events
    assert ev.dtype == EVENT_DTYPE and len(ev) == 5
    assert ev["t"].tolist() == [10000, 20000, 60000, 70000, 120000]
    assert ev["x"].tolist() == [1, 19, 5, 6, 0] and ev["y"].tolist() == [2, 15, 5, 5, 0]
    assert ev["p"].tolist() == [1, 0, 1, 1, 0]
    spans = [(w.t_start_us, w.t_end_us) for w in seq.windows]
    assert spans == [(0, 50000), (50000, 100000)]
    assert [int(w.mask.sum()) for w in seq.windows] == [20, 10]
    assert [w.object_ids for w in seq.windows] == [(1,), (1, 2)]
    assert np.array_equal(seq.windows[1].labels == 2, MASK1[1] == 2000)
    following = next(load_evimo(tmp_path, window_mode="following"))
    assert [(w.t_start_us, w.t_end_us) for w in following.windows] == [
        (50000, 100000),
        (100000, 150000),
    ]


def test_evimo1_meta_as_json_text_and_subset_aliases(tmp_path):
    meta_text = json.dumps(evimo_meta([0.05, 0.10], W1, H1))
    write_evimo1(tmp_path / "eval_tabletop_npz" / "npz" / "seq_02.npz", meta=meta_text)
    write_evimo1(tmp_path / "boxes" / "seq_00.npz")
    srcs = find_evimo_sequences(tmp_path)
    assert [(s.subset, s.name) for s in srcs] == [("box", "seq_00"), ("tabletop", "seq_02")]
    (seq,) = list(load_evimo(tmp_path, subsets=["tabletop"]))
    assert [(w.t_start_us, w.t_end_us) for w in seq.windows] == [(0, 50000), (50000, 100000)]


def test_evimo_meta_pickle_is_restricted(tmp_path):
    path = write_evimo1(tmp_path / "box" / "evil.npz", meta=np.array(Fraction(1, 2), dtype=object))
    with pytest.raises(DatasetLayoutError, match=r"refusing to unpickle fractions\.Fraction"):
        read_npz_meta(path)


def test_evimo2v2_folder_loader(tmp_path):
    seq_dir = write_evimo2(tmp_path / "samsung_mono" / "imo" / "eval" / "scene13_dyn_test_00")
    (src,) = find_evimo_sequences(tmp_path)
    assert (src.format, src.subset, src.name) == (
        "evimo2v2_npz",
        "samsung_mono/imo/eval",
        "scene13_dyn_test_00",
    )
    (seq,) = list(load_evimo(tmp_path))
    assert seq.sensor_size == (8, 6, 2)
    assert seq.events["t"].tolist() == [1000, 1500, 3100, 4200, 9900]
    assert seq.events["x"].tolist() == [0, 3, 7, 7, 1]
    # frames at 2 ms and 4 ms kept (id 11 has no mask): preceding windows of 2 ms
    assert [(w.t_start_us, w.t_end_us) for w in seq.windows] == [(0, 2000), (2000, 4000)]
    assert [int(w.mask.sum()) for w in seq.windows] == [4, 4]
    assert [w.object_ids for w in seq.windows] == [(1,), (3,)]
    assert any("1 of 3 frames have no mask" in n for n in seq.notes)
    assert any("Samsung" in n for n in seq.notes)
    # the folder itself is a valid PATH too
    assert len(list(load_evimo(seq_dir))) == 1


def test_evimo2_columns_that_no_cast_keeps_are_refused_naming_the_file(tmp_path):
    """A NaN time, a polarity other than 0/1, a fractional coordinate and columns of
    different lengths are each one line naming the file, never cast."""
    seq = write_evimo2(tmp_path / "imo" / "seq")
    t = np.array([0.001, np.nan, 0.0031, 0.0042, 0.0099])
    np.save(seq / "dataset_events_t.npy", t)
    with pytest.raises(DatasetLayoutError) as e:
        list(load_evimo(tmp_path))
    assert str(e.value) == f"{seq / 'dataset_events_t.npy'}: t holds nan, not a finite time"
    np.save(seq / "dataset_events_t.npy", t[[0, 0, 2, 3, 4]])
    np.save(seq / "dataset_events_p.npy", np.array([1, 0, 7, 1, 0], dtype=np.uint8))
    with pytest.raises(DatasetLayoutError) as e:
        list(load_evimo(tmp_path))
    assert str(e.value) == f"{seq}: p holds values other than 0/1 or -1/1, e.g. 7"
    np.save(seq / "dataset_events_p.npy", np.array([1, 0, 1, 1], dtype=np.uint8))
    with pytest.raises(DatasetLayoutError) as e:
        list(load_evimo(tmp_path))
    assert str(e.value) == f"{seq}: event columns differ in length: t 5, x 5, y 5, p 4"
    np.save(seq / "dataset_events_p.npy", np.array([1, 0, 1, 1, 0], dtype=np.uint8))
    np.save(seq / "dataset_events_xy.npy", np.array([[0, 0], [3.7, 4], [7, 5], [7, 5], [1, 1]]))
    with pytest.raises(DatasetLayoutError) as e:
        list(load_evimo(tmp_path))
    assert str(e.value) == f"{seq}: x holds values that are not whole numbers, e.g. 3.7"


def test_evimo_wrong_layout_errors(tmp_path):
    with pytest.raises(DatasetLayoutError, match=r"expected: PATH/<subset>/<sequence>\.npz"):
        find_evimo_sequences(tmp_path)
    (tmp_path / "box" / "seq_01").mkdir(parents=True)
    (tmp_path / "box" / "seq_01" / "meta.txt").write_text("{}")
    (tmp_path / "box" / "seq_01" / "events.txt").write_text("")
    with pytest.raises(DatasetLayoutError, match="TXT format"):
        find_evimo_sequences(tmp_path)
    np.savez(tmp_path / "box" / "other.npz", events=np.zeros((2, 4)))
    with pytest.raises(DatasetLayoutError, match=r"other\.npz.*\['mask', 'meta'\]"):
        find_evimo_sequences(tmp_path)
    (tmp_path / "box" / "other.npz").unlink()
    write_evimo1(tmp_path / "box" / "seq_01.npz")
    with pytest.raises(DatasetLayoutError, match=r"subset\(s\) \['wall'\] not found"):
        find_evimo_sequences(tmp_path, subsets=["wall"])
    bad = write_evimo1(tmp_path / "fast" / "seq_03.npz", meta=evimo_meta([0.05], W1, H1))
    with pytest.raises(DatasetLayoutError, match="1 entries but 'mask' 2 frames"):
        list(load_evimo(bad))
    partial = tmp_path / "evimo2" / "seq"
    partial.mkdir(parents=True)
    np.savez(partial / "dataset_info.npz", meta=evimo_meta([0.1], 4, 4))
    with pytest.raises(DatasetLayoutError, match="EVIMO2v2 folder without"):
        find_evimo_sequences(tmp_path)


# ----------------------------------------------------------------------------------------
# LLE-VOS


def write_llevos(root: Path) -> Path:
    """Two sequences: 00001 (.npz events, 3 frames) and 00002 (.npy N x 4, 2 frames)."""
    base = root / "LLE_VOS"
    ann = rect((12, 16), 2, 5, 3, 7, 1, np.uint8)  # 12 px of object 1
    ann2 = ann.copy()
    ann2[8:10, 10:12] = 2  # + 4 px of object 2
    write_png_p(base / "Annotations" / "00001" / "00000.png", ann)
    write_png_p(base / "Annotations" / "00001" / "00001.png", np.zeros((12, 16), np.uint8))
    write_png_p(base / "Annotations" / "00001" / "00002.png", ann2)
    ev = base / "Lowlight_event" / "00001"
    ev.mkdir(parents=True)
    np.savez(
        ev / "00000.npz",
        x=np.array([1, 2]),
        y=np.array([3, 4]),
        t=np.array([100, 150]),
        p=np.array([1, -1]),
    )
    np.savez(
        ev / "00001.npz",
        x=np.array([5, 6, 7]),
        y=np.array([0, 0, 11]),
        t=np.array([200, 230, 260]),
        p=np.array([0, 1, 1]),
    )
    np.savez(
        ev / "00002.npz", x=np.array([15]), y=np.array([1]), t=np.array([300]), p=np.array([1])
    )
    write_png_p(base / "Annotations" / "00002" / "00000.png", ann)
    write_png_p(base / "Annotations" / "00002" / "00001.png", ann)
    ev2 = base / "Lowlight_event" / "00002"
    ev2.mkdir(parents=True)
    np.save(ev2 / "00000.npy", np.array([[0, 0, 10, 1], [1, 1, 20, 0]], dtype=np.float64))
    np.save(ev2 / "00001.npy", np.array([[2, 2, 40, 1]], dtype=np.float64))
    (base / "Lowlight_Images" / "00001").mkdir(parents=True)
    (base / "val_indoor.txt").write_text("00001\n")
    return root


def test_llevos_loader(tmp_path):
    seqs = list(load_llevos(write_llevos(tmp_path)))
    assert [(s.dataset, s.subset, s.name) for s in seqs] == [
        ("llevos", "val_indoor", "00001"),
        ("llevos", "all", "00002"),
    ]
    s1, s2 = seqs
    assert s1.sensor_size == (16, 12, 2)
    assert s1.events["t"].tolist() == [100, 150, 200, 230, 260, 300]
    assert s1.events["p"].tolist() == [1, 0, 0, 1, 1, 1]
    spans = [(w.t_start_us, w.t_end_us) for w in s1.windows]
    assert spans == [(100, 200), (200, 300), (300, 301)]
    assert [int(w.mask.sum()) for w in s1.windows] == [12, 0, 16]
    assert s1.windows[2].object_ids == (1, 2)
    assert s2.events["t"].tolist() == [10, 20, 40]
    assert [(w.t_start_us, w.t_end_us) for w in s2.windows] == [(10, 40), (40, 41)]
    ms = next(load_llevos(tmp_path, sequences=["00002"], config=LLEVOSConfig(time_unit="ms")))
    assert ms.events["t"].tolist() == [10000, 20000, 40000]


def test_llevos_wrong_layout_errors(tmp_path):
    with pytest.raises(DatasetLayoutError, match=r"expected: PATH/Annotations/<seq>/<frame>\.png"):
        list(load_llevos(tmp_path))
    root = write_llevos(tmp_path / "d")
    ev = root / "LLE_VOS" / "Lowlight_event" / "00001"
    np.savez(
        ev / "00002.npz", x=np.array([16]), y=np.array([1]), t=np.array([300]), p=np.array([1])
    )
    with pytest.raises(DatasetLayoutError, match=r"00002\.npz: events reach x 16\.\.16"):
        list(load_llevos(root, sequences=["00001"]))
    np.savez(ev / "00002.npz", x=np.array([1]), y=np.array([1]), t=np.array([250]), p=np.array([1]))
    with pytest.raises(DatasetLayoutError, match=r"00002\.npz: starts at t=250 µs before"):
        list(load_llevos(root, sequences=["00001"]))
    np.savez(ev / "00002.npz", x=np.array([1]), y=np.array([1]), t=np.array([np.inf]), p=[1])
    with pytest.raises(DatasetLayoutError, match=r"00002\.npz: t holds inf, not a finite time$"):
        list(load_llevos(root, sequences=["00001"]))
    np.savez(ev / "00002.npz", x=np.array([1]), y=np.array([1]), t=np.array([300]), p=[5])
    with pytest.raises(DatasetLayoutError, match=r"00002\.npz: p holds values other than 0/1"):
        list(load_llevos(root, sequences=["00001"]))
    np.savez(ev / "00002.npz", a=np.zeros(3))
    with pytest.raises(DatasetLayoutError, match=r"00002\.npz: keys \['a'\]"):
        list(load_llevos(root, sequences=["00001"]))
    with pytest.raises(DatasetLayoutError, match=r"sequence\(s\) \['00009'\] not found"):
        list(load_llevos(root, sequences=["00009"]))


def test_mask_window_checks():
    with pytest.raises(ValueError, match="empty time window"):
        MaskWindow(5, 5, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="must be 2-D"):
        MaskWindow(0, 5, np.zeros(3))


def test_zip_is_npz(tmp_path):
    # sanity: the synthetic EVIMO1 file holds the documented keys
    path = write_evimo1(tmp_path / "wall" / "seq.npz")
    names = {n[:-4] for n in zipfile.ZipFile(path).namelist()}
    assert names == {
        "events",
        "index",
        "classical",
        "discretization",
        "K",
        "D",
        "depth",
        "mask",
        "meta",
    }


def test_generic_loader_says_when_masks_differ_from_sensor(tmp_path):
    from wander_env.events import make_events
    from wander_env.events.io import EventRecording, write_events

    write_png_p(tmp_path / "m" / "000001_5000.png", rect((6, 8), 0, 2, 0, 2, 1, np.uint8))
    write_png_p(tmp_path / "m" / "000002_10000.png", rect((6, 8), 0, 2, 0, 2, 1, np.uint8))
    rec = EventRecording(make_events([0, 15], [0, 11], [10, 6000], [1, 0]), (16, 12, 2))
    write_events(tmp_path / "ev.h5", rec)
    seq = load_generic(tmp_path / "ev.h5", tmp_path / "m", name="toy")
    assert (seq.name, seq.sensor_size, seq.n_events) == ("toy", (16, 12, 2), 2)
    assert [(w.t_start_us, w.t_end_us) for w in seq.windows] == [(0, 5000), (5000, 10000)]
    assert any("resized nearest-neighbour to sensor 12x16" in n for n in seq.notes)
