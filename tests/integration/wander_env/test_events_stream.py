"""The streaming writers (wander_env.events.stream) and the one-line failures of long commands."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from experiments.cli.errors import current_run, long_command
from experiments.runs.folder import RunFolder
from wander_env.events import make_events
from wander_env.events.io import EventFileError, read_events
from wander_env.events.stream import EventStreamWriter, H5Appender, OutputError


def step(k: int, n: int = 100) -> np.ndarray:
    t = np.arange(n) + k * 1000
    return make_events(np.arange(n) % 8, np.arange(n) % 4, t, np.arange(n) % 2)


def test_chunks_are_flushed_as_they_fill_and_an_unfinished_file_says_where_it_stops(tmp_path):
    path = tmp_path / "events.h5"
    writer = EventStreamWriter(path, (8, 4, 2), {"seed": 3}, chunk_events=250, flush_s=1e9)
    for k in range(7):
        writer.append(step(k))
    # the chunks [0, 250) and [250, 500) as they filled, each written once; the rest waits
    assert (writer.flushed, writer.events_written) == (500, 700)
    with h5py.File(path, "r") as f:
        assert [f["events"][c].id.get_num_chunks() for c in "xytp"] == [2, 2, 2, 2]
    writer._abandon()  # as if the process died here: the buffered 200 are lost
    rec = read_events(path)
    assert len(rec.events) == 500 and rec.events["t"][-1] == 4099
    assert rec.metadata == {"seed": 3, "incomplete": {"events": 500, "last_t_us": 4099}}


def test_a_timed_flush_writes_every_buffered_event(tmp_path):
    writer = EventStreamWriter(tmp_path / "events.h5", (8, 4, 2), chunk_events=250, flush_s=0)
    for k in range(3):
        writer.append(step(k))
        assert writer.flushed == writer.events_written == 100 * (k + 1)
    writer.close()
    assert len(read_events(tmp_path / "events.h5").events) == 300


def _tear(path: Path, column: str, at: int) -> None:
    """Overwrite the stored bytes of the chunk of ``events/column`` holding event ``at``,
    as a kill while the writer rewrote it would leave them."""
    with h5py.File(path, "r") as f:
        info = f["events"][column].id.get_chunk_info_by_coord((at,))
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset)
        fh.write(b"\xff" * info.size)


def test_a_stream_killed_while_it_rewrote_its_last_chunk_reads_up_to_that_chunk(tmp_path):
    path = tmp_path / "events.h5"
    writer = EventStreamWriter(path, (8, 4, 2), {"seed": 3}, chunk_events=250, flush_s=1e9)
    for k in range(6):
        writer.append(step(k))
    writer.flush()  # as a timed flush does: the partial chunk [500, 600) written too
    assert writer.flushed == 600
    writer._abandon()
    _tear(path, "t", 599)
    rec = read_events(path)
    assert np.array_equal(rec.events, np.concatenate([step(k) for k in range(5)]))
    stop = {"events": 500, "last_t_us": 4099, "torn_events": 100}
    assert rec.metadata == {"seed": 3, "incomplete": stop}


def _off_sensor(f: h5py.File) -> None:
    f["events/x"][550] = 200  # another column's numbers where x's chunk was


def _claims_ahead(f: h5py.File) -> None:
    for name in ("x", "y", "t", "p"):  # the new length on disk before its events
        f["events"][name].resize((700,))
    f.attrs["events_flushed"] = 700


@pytest.mark.parametrize("damage", [_off_sensor, _claims_ahead])
def test_a_last_chunk_that_decodes_to_events_no_writer_wrote_is_dropped(tmp_path, damage):
    path = tmp_path / "events.h5"
    writer = EventStreamWriter(path, (8, 4, 2), {"seed": 3}, chunk_events=250, flush_s=1e9)
    for k in range(6):
        writer.append(step(k))
    writer.flush()
    writer._abandon()
    with h5py.File(path, "r+") as f:
        damage(f)
    rec = read_events(path)
    assert len(rec.events) == 500 and rec.events["t"][-1] == 4099
    torn = 100 if damage is _off_sensor else 200
    assert rec.metadata["incomplete"] == {"events": 500, "last_t_us": 4099, "torn_events": torn}


def test_a_torn_chunk_before_the_last_is_an_error_not_a_shorter_recording(tmp_path):
    path = tmp_path / "events.h5"
    writer = EventStreamWriter(path, (8, 4, 2), {"seed": 3}, chunk_events=250, flush_s=1e9)
    for k in range(6):
        writer.append(step(k))
    writer._abandon()
    _tear(path, "x", 0)
    with pytest.raises(EventFileError, match=r"events\.h5.*not a readable HDF5 file"):
        read_events(path)


def test_a_finished_stream_equals_the_events_and_takes_the_final_metadata(tmp_path):
    path = tmp_path / "events.h5"
    with EventStreamWriter(path, (8, 4, 2), {"seed": 3}, chunk_events=64) as writer:
        for k in range(5):
            writer.append(step(k))
        writer.append(step(5)[:0])  # an empty step is fine
    with EventStreamWriter(tmp_path / "b.h5", (8, 4, 2), chunk_events=64) as other:
        other.append(step(0))
    other.close({"summary": 1})  # idempotent; already complete
    rec = read_events(path)
    assert np.array_equal(rec.events, np.concatenate([step(k) for k in range(5)]))
    assert rec.metadata == {"seed": 3}
    with h5py.File(path) as f:
        assert bool(f.attrs["complete"]) and f["events/x"].maxshape == (None,)


def test_a_finished_stream_has_the_dsec_index_of_its_events(tmp_path):
    """ms_to_idx built chunk by chunk equals the index of the whole recording, and seeks."""
    from wander_env.events.hdf5_index import ms_to_idx, read_h5_window

    path = tmp_path / "events.h5"
    rng = np.random.default_rng(4)
    steps = []
    t0 = 0
    for _ in range(40):  # steps of 0-300 events spread over 0.5-3.5 ms, gaps included
        n = int(rng.integers(0, 300))
        t = t0 + np.sort(rng.integers(0, int(rng.integers(500, 3500)), n))
        t0 = (int(t[-1]) if n else t0) + int(rng.integers(0, 2500))
        steps.append(make_events(t % 8, t % 4, t, t % 2))
    with EventStreamWriter(path, (8, 4, 2), chunk_events=97) as writer:
        for ev in steps:
            writer.append(ev)
    events = np.concatenate(steps)
    with h5py.File(path) as f:
        index, offset = f["ms_to_idx"][()], int(f["t_offset"][()])
    assert offset == 0 and index.dtype == np.uint64
    assert np.array_equal(index, ms_to_idx(events["t"]))
    assert len(index) == int(events["t"][-1]) // 1000 + 1
    window = read_h5_window(path, 20_000, 31_000)
    keep = (events["t"] >= 20_000) & (events["t"] < 31_000)
    assert np.array_equal(window, events[keep])


def test_both_writers_of_an_h5_write_the_same_events_metadata_and_index(tmp_path):
    """EventStreamWriter and write_events agree: strict metadata (NaN as null, NumPy
    scalars as numbers), the same ms_to_idx and t_offset, for a clock that starts late."""
    from wander_env.events.hdf5_index import read_h5_window
    from wander_env.events.io import EventRecording, write_events

    start = 1_605_537_493_718_345  # a real clock: t_offset is not 0
    steps = [step(k) for k in range(9)]
    for ev in steps:
        ev["t"] += start
    steps.insert(4, steps[0][:0])
    events = np.concatenate(steps)
    meta = {"nan": float("nan"), "half": np.float32(0.5), "n": np.int64(7), "v": [np.inf]}
    streamed, whole = tmp_path / "streamed.h5", tmp_path / "whole.h5"
    writer = EventStreamWriter(streamed, (8, 4, 2), {"seed": 1}, chunk_events=97)
    for ev in steps:
        writer.append(ev)
    writer.close(meta)  # replaces the metadata given at creation
    write_events(whole, EventRecording(events, (8, 4, 2), meta))
    expected = {"nan": None, "half": 0.5, "n": 7, "v": [None]}
    for path in (streamed, whole):
        rec = read_events(path)
        assert np.array_equal(rec.events, events) and rec.metadata == expected
        with h5py.File(path) as f:
            assert json.loads(f.attrs["metadata"]) == expected
            index, offset = f["ms_to_idx"][()], int(f["t_offset"][()])
        assert offset == 1_605_537_493_718_000 and index.dtype == np.uint64
        assert index.tolist() == [100 * k for k in range(9)]
        window = read_h5_window(path, start + 2000, start + 5000)
        assert np.array_equal(window, np.concatenate(steps[2:6]))  # t in [2, 5) ms


def test_an_empty_streamed_recording_has_the_index_of_an_empty_one_and_reads(tmp_path):
    from wander_env.events.hdf5_index import read_h5_window
    from wander_env.events.io import EventRecording, write_events

    streamed, whole = tmp_path / "streamed.h5", tmp_path / "whole.h5"
    with EventStreamWriter(streamed, (8, 4, 2), {"note": "no events"}) as writer:
        writer.append(step(0)[:0])
    write_events(whole, EventRecording(step(0)[:0], (8, 4, 2), {"note": "no events"}))
    for path in (streamed, whole):
        with h5py.File(path) as f:
            index, offset = f["ms_to_idx"][()], int(f["t_offset"][()])
        assert index.dtype == np.uint64 and index.tolist() == [] and offset == 0
        assert read_h5_window(path, 0, 10_000).tolist() == []
        assert read_events(path).metadata == {"note": "no events"}


def test_out_of_order_or_off_sensor_steps_are_refused_naming_the_file(tmp_path):
    path = tmp_path / "events.h5"
    with EventStreamWriter(path, (8, 4, 2)) as writer:
        writer.append(step(1))
        with pytest.raises(ValueError, match=r"events\.h5: events start at t=0 before"):
            writer.append(step(0))
        with pytest.raises(ValueError, match=r"x\[0\]=9 is outside the sensor"):
            writer.append(make_events([9], [0], [5000], [1]))


def test_h5_appender_rows_and_a_field_with_nothing_per_row(tmp_path):
    path = tmp_path / "truth.h5"
    fields = {"t": (np.float64, ()), "mask": (np.uint8, (2, 3)), "centres": (np.float32, (0, 2))}
    with H5Appender(path, fields, {"names": "none"}, chunk_rows=2) as truth:
        for k in range(5):
            truth.append(t=k / 10, mask=np.full((2, 3), k), centres=np.zeros((0, 2)))
    with h5py.File(path) as f:
        assert f["t"][()].tolist() == [0.0, 0.1, 0.2, 0.3, 0.4]
        assert f["mask"][:, 0, 0].tolist() == [0, 1, 2, 3, 4]
        assert f["centres"].shape == (5, 0, 2)
        assert bool(f.attrs["complete"]) and f.attrs["rows"] == 5 and f.attrs["names"] == "none"


@pytest.mark.parametrize("given", [True, False], ids=["out", "default folder"])
def test_long_command_turns_a_write_failure_into_one_line_and_marks_the_folder(tmp_path, given):
    # The command's failure handling finds the folder the command named, --out or not.
    app = typer.Typer()

    @app.command()
    @long_command("wander demo")
    def demo(ctx: typer.Context, out: str | None = None) -> None:
        run = RunFolder.new("demo", out, root=tmp_path / "runs", current=current_run(ctx))
        run.create()
        cause = OSError(errno.ENOSPC, "No space left on device")
        raise OutputError(run.path / "events.h5", cause)

    result = CliRunner().invoke(app, ["--out", str(tmp_path / "run")] if given else [])
    (folder,) = [tmp_path / "run"] if given else list((tmp_path / "runs").iterdir())
    assert result.exit_code == 1
    assert result.stderr.strip() == (
        f"wander demo: cannot write {folder / 'events.h5'}: No space left on device; "
        f"'{folder}' is marked INCOMPLETE"
    )
    metrics = json.loads((folder / "metrics.json").read_text())
    assert metrics["incomplete"] is True and metrics["error"].startswith("OutputError: ")
    assert (folder / "INCOMPLETE").read_text().startswith("cannot write ")
