"""SpeckSource against the fake samna in tests/fake_samna.py (the real samna is never imported)."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest
from fake_samna import FakeSamna, FakeSpeck, install
from locations import REALDATA, ROOT
from polling import LIMIT_S, wait_until

import hardware.samna_import as samna_import_mod
from hardware.event_source import EventSource
from hardware.samna_import import SamnaUnavailableError, import_samna
from hardware.speck import SpeckParams, SpeckSource
from wander_env.events import EVENT_DTYPE, validate_events

WALK = REALDATA / "dvs128_people" / "alex_walking_for_10secs_txyp.npy"
DURATION_US = 300_000
T_FIRST_US = 1_000  # the first recorded event comes 1 ms after the stop-watch reset


def recording(duration_us: int = DURATION_US) -> np.ndarray:
    """Events (t from T_FIRST_US) of a real DVS128 recording, or synthetic ones without it."""
    if WALK.is_file():
        raw = np.load(WALK)
        raw = raw[raw["t"] < raw["t"][0] + duration_us]
        ev = np.empty(len(raw), EVENT_DTYPE)
        for f in ("x", "y", "p"):
            ev[f] = raw[f]
        ev["t"] = raw["t"] - raw["t"][0] + T_FIRST_US
        return ev
    rng = np.random.default_rng(1)
    n = 3000
    ev = np.empty(n, EVENT_DTYPE)
    ev["x"], ev["y"], ev["p"] = (
        rng.integers(0, 128, n),
        rng.integers(0, 128, n),
        rng.integers(0, 2, n),
    )
    ev["t"] = np.sort(rng.integers(0, duration_us, n)) + T_FIRST_US
    return ev


def fake_with(*devices: tuple[str, str, FakeSpeck | None]) -> FakeSamna:
    return FakeSamna(devices)


@pytest.fixture
def events() -> np.ndarray:
    return recording()


@pytest.fixture
def fake(monkeypatch, events) -> FakeSamna:
    return install(
        monkeypatch,
        fake_with(
            ("DVXplorer", "dvx-1", None),
            ("Speck2fModuleDevKit", "sf-1", FakeSpeck(events, other_every=97)),
        ),
    )


def wait_received(src: SpeckSource, n: int) -> None:
    wait_until(lambda: src.stats["received"] >= n)


def read_all(src: SpeckSource, n_expected: int, window_us: int = 50_000, limit_s: float = LIMIT_S):
    chunks, total, t_end = [], 0, time.monotonic() + limit_s
    while total < n_expected and time.monotonic() < t_end:
        chunk = src.read(duration_us=window_us)
        chunks.append(chunk)
        total += len(chunk)
    return chunks


# -- samna availability ------------------------------------------------------------------


def test_importing_hardware_modules_does_not_import_samna():
    code = (
        "import sys, hardware.speck, hardware.replay, hardware.event_source; "
        "assert 'samna' not in sys.modules, 'samna imported at module level'"
    )
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)


def test_samna_missing_gives_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "samna", None)
    with pytest.raises(RuntimeError, match="samna is not installed") as info:
        SpeckSource().start()
    assert "pip install" in str(info.value)


def test_samna_not_found_on_path(monkeypatch):
    monkeypatch.delitem(sys.modules, "samna", raising=False)
    monkeypatch.setattr(samna_import_mod.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(SamnaUnavailableError, match="not installed"):
        import_samna()


def _guard_import(monkeypatch):
    def refuse(name, *args, **kwargs):
        raise AssertionError(f"import_module({name!r}) must not run for the placeholder")

    monkeypatch.setattr(samna_import_mod.importlib, "import_module", refuse)


def test_pypi_placeholder_is_recognised_without_running_it(monkeypatch, tmp_path):
    pkg = tmp_path / "samna"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(
        "PYPI_SAMNA = True\n"
        "def install_real_samna():\n    raise SystemExit('would pip install')\n"
        "install_real_samna()\n"
    )
    monkeypatch.delitem(sys.modules, "samna", raising=False)
    monkeypatch.syspath_prepend(str(tmp_path))
    _guard_import(monkeypatch)
    with pytest.raises(SamnaUnavailableError, match="PyPI placeholder") as info:
        SpeckSource().start()
    assert "index-url" in str(info.value)


def test_the_venvs_samna_placeholder_is_refused(monkeypatch):
    import importlib.util

    monkeypatch.delitem(sys.modules, "samna", raising=False)
    spec = importlib.util.find_spec("samna")
    if spec is None or not samna_import_mod._is_stub_source(spec.origin):
        pytest.skip("this environment has no PyPI samna placeholder")
    _guard_import(monkeypatch)
    with pytest.raises(SamnaUnavailableError, match="placeholder"):
        import_samna()


def test_placeholder_failing_at_import_is_reported(monkeypatch, tmp_path):
    pkg = tmp_path / "samna"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(
        "import subprocess\nraise subprocess.CalledProcessError(1, ['pip', 'install', 'samna'])\n"
    )
    monkeypatch.delitem(sys.modules, "samna", raising=False)
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(SamnaUnavailableError, match="CalledProcessError") as info:
        import_samna()
    assert "placeholder" in str(info.value)
    sys.modules.pop("samna", None)


def test_placeholder_module_object_is_refused(monkeypatch):
    import types

    stub = types.ModuleType("samna")
    stub.PYPI_SAMNA = True
    monkeypatch.setitem(sys.modules, "samna", stub)
    with pytest.raises(SamnaUnavailableError, match="placeholder"):
        import_samna()


# -- device choice -----------------------------------------------------------------------


def test_no_speck_lists_what_was_found(monkeypatch, events):
    install(monkeypatch, fake_with(("DVXplorer", "dvx-1", None), ("Davis 346", "d-7", None)))
    with pytest.raises(RuntimeError, match="Speck2f or Speck2e") as info:
        SpeckSource().start()
    message = str(info.value)
    assert "DVXplorer" in message and "Davis 346" in message and "'d-7'" in message


def test_no_device_at_all(monkeypatch):
    install(monkeypatch, fake_with())
    with pytest.raises(RuntimeError, match="no devices at all"):
        SpeckSource().start()


def test_preferred_family_and_serial_are_chosen(monkeypatch, events):
    fake = install(
        monkeypatch,
        fake_with(
            ("Speck2eDevKit", "se-1", FakeSpeck(events)),
            ("DVXplorer", "dvx-1", None),
            ("Speck2fDevKit", "sf-1", FakeSpeck(events)),
            ("Speck2fModuleDevKit", "sf-2", FakeSpeck(events)),
        ),
    )
    with SpeckSource() as src:
        assert src.device_type_name == "Speck2fDevKit"
        assert fake.handles[-1].info.serial_number == "sf-1"
    with SpeckSource(serial_number="sf-2") as src:
        assert src.device_type_name == "Speck2fModuleDevKit"
    with SpeckSource(device_type_prefixes=("Speck2e",)) as src:
        assert src.device_type_name == "Speck2eDevKit"
        assert fake.handles[-1].family == "speck2e"
        assert isinstance(
            fake.handles[-1].applied[-1], fake.module.speck2e.configuration.SpeckConfiguration
        )


def test_params_are_validated():
    with pytest.raises(ValueError, match=r"read_timeout_ms must be an int in 1\.\.10000"):
        SpeckParams(read_timeout_ms=0.05)  # seconds given for ms
    with pytest.raises(ValueError, match="queue_events must be >= 1"):
        SpeckParams(queue_events=0)
    with pytest.raises(TypeError, match="no_such_option"):
        SpeckSource(no_such_option=1)


# -- configuration and events -----------------------------------------------------------


def test_configuration_streams_raw_dvs_only(fake):
    with SpeckSource() as src:
        handle = fake.handles[-1]
        config = handle.applied[-1]
        dvs = config.dvs_layer
        assert dvs.raw_monitor_enable is True
        assert dvs.monitor_enable is False
        assert dvs.pass_sensor_events is True
        assert not any(d.enable for d in dvs.destinations)
        assert not any(layer.monitor_enable for layer in config.cnn_layers)
        assert handle.get_stop_watch().calls[:2] == ["set_enable_value(True)", "reset()"]
        assert src.sensor_size == (128, 128, 2)
        assert src.stats["sensor_size_from"].startswith("configuration")
        assert isinstance(src, EventSource)


def test_events_arrive_exactly_and_other_events_are_counted(fake, events):
    # a generous margin: windows close on the arrival of a later event, not on the host clock
    with SpeckSource(latency_margin_us=500_000) as src:
        chunks = read_all(src, len(events))
        stats = src.stats
    got = np.concatenate(chunks)
    assert len(got) == len(events)
    for f in ("x", "y", "t", "p"):
        assert np.array_equal(got[f], events[f]), f
    validate_events(got, (128, 128, 2))
    assert got.dtype == EVENT_DTYPE
    # each window holds exactly its events
    start = 0
    for i, chunk in enumerate(chunks):
        if len(chunk):
            assert chunk["t"].min() >= i * 50_000 and chunk["t"].max() < (i + 1) * 50_000
        start += len(chunk)
    speck = fake.handles[-1].speck
    assert speck.emitted_other["Spike"] > 0 and speck.emitted_other["ReadoutPinValue"] > 0
    assert stats["other_events"] == speck.emitted_other
    assert stats["other_total"] == sum(speck.emitted_other.values())
    assert stats["received"] == stats["delivered"] == len(events)
    assert src.dropped == 0


def test_drain_read_and_timestamp_wraparound(monkeypatch, events):
    short = events[events["t"] < 150_000]
    offset = (1 << 32) - 60_000  # the device counter wraps 60 ms into the stream
    install(
        monkeypatch, fake_with(("Speck2fDevKit", "sf", FakeSpeck(short, timestamp_offset=offset)))
    )
    with SpeckSource() as src:
        wait_received(src, len(short))
        got = src.read()
        assert src.stats["wraps"] == 1
        assert src.read().size == 0
    assert np.array_equal(got["t"], short["t"] + offset)
    assert np.all(np.diff(got["t"]) >= 0)


def test_queue_overflow_drops_oldest_and_never_blocks_the_reader(monkeypatch, events):
    fake = install(monkeypatch, fake_with(("Speck2fDevKit", "sf", FakeSpeck(events))))
    capacity = 500
    with SpeckSource(queue_events=capacity) as src:
        time.sleep(DURATION_US / 1e6)  # a consumer that does not read at all
        wait_received(src, len(events))
        stats = src.stats
        got = src.read()
        sink = fake.handles[-1]._sinks[0]
        assert stats["received"] == len(events)
        assert stats["dropped_overflow"] == len(events) - capacity
        assert src.dropped >= len(events) - capacity
        assert len(got) == capacity
        assert np.array_equal(got["t"], events["t"][-capacity:])  # the newest are kept
        # the reader polls the device on past a full queue (it is not blocked by it)
        delivered = np.cumsum([n for _, _, n in sink.calls])
        full = int(np.searchsorted(delivered, capacity))  # the call that filled the queue
        assert wait_until(lambda: len(sink.calls) > full + 1)


def test_late_events_are_counted_not_delivered(monkeypatch, events):
    install(monkeypatch, fake_with(("Speck2fDevKit", "sf", FakeSpeck(events))))
    with SpeckSource(latency_margin_us=1_000_000) as src:
        first = src.read(until_t_us=T_FIRST_US + 10_000, timeout_s=0.0)  # returns at once
        time.sleep(0.05)
        rest = src.read(until_t_us=60_000)
        assert np.all(rest["t"] >= T_FIRST_US + 10_000)
        assert src.stats["late"] == int(np.sum(events["t"] < T_FIRST_US + 10_000)) - len(first)
        assert src.dropped == src.stats["late"]


def test_window_arguments_are_checked(fake):
    with SpeckSource() as src:
        with pytest.raises(ValueError, match="give duration_us or until_t_us, not both"):
            src.read(duration_us=10, until_t_us=20)
        src.read(until_t_us=5_000)
        with pytest.raises(ValueError, match=r"until_t_us=4000 is before the end"):
            src.read(until_t_us=4_000)
    with pytest.raises(RuntimeError, match="closed"):
        src.read(duration_us=1)
    with pytest.raises(RuntimeError, match="before start"):
        SpeckSource().read(duration_us=1)


# -- closing ----------------------------------------------------------------------------------


def assert_closed(fake: FakeSamna, src: SpeckSource) -> None:
    handle = fake.handles[-1]
    assert handle.closed
    assert handle.get_stop_watch().enabled is False
    assert handle.get_stop_watch().calls[-1] == "set_enable_value(False)"
    assert not handle._sinks[0]._graph.running
    assert src._thread is None
    assert not src.stats["reader_alive"]
    assert src.stats["close_errors"] == []
    assert fake.close_calls == 1


def test_close_is_clean_and_idempotent(fake):
    src = SpeckSource()
    src.start()
    thread = src._thread
    src.read(duration_us=20_000)
    src.close()
    src.close()
    assert not thread.is_alive()
    assert_closed(fake, src)
    assert fake.get_unopened_devices()[-1].device_type_name == "Speck2fModuleDevKit"


@pytest.mark.parametrize("error", [ValueError, KeyboardInterrupt])
def test_exception_inside_with_closes(fake, error):
    with pytest.raises(error):
        with SpeckSource() as src:
            src.read(duration_us=10_000)
            raise error("boom")
    assert_closed(fake, src)


def test_failure_while_opening_closes_the_device(monkeypatch, events):
    fake = install(monkeypatch, fake_with(("Speck2fDevKit", "sf", FakeSpeck(events))))
    original = fake.open_device

    def open_failing(info):
        handle = original(info)
        handle.fail_on_apply = True
        return handle

    fake.module.device.open_device = open_failing
    src = SpeckSource()
    with pytest.raises(RuntimeError, match="apply_configuration failed"):
        src.start()
    assert fake.handles[-1].closed and src.closed
    assert not fake.handles[-1]._sinks[0]._graph.running


def test_reader_failure_is_raised_by_read(monkeypatch, events):
    fake = install(monkeypatch, fake_with(("Speck2fDevKit", "sf", FakeSpeck(events))))
    with SpeckSource() as src:
        sink = fake.handles[-1]._sinks[0]

        def broken(timeout):
            raise OSError("USB gone")

        sink.get_events_blocking = broken
        assert wait_until(lambda: src.stats["reader_error"])  # the reader's next poll fails
        with pytest.raises(RuntimeError, match="USB gone"):
            src.read(duration_us=200_000)
    assert fake.handles[-1].closed
