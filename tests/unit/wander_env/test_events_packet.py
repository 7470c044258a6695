"""EventPacket: one step's events as one value (equality, pickling, array access)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from wander_env.events import make_events
from wander_env.events.packet import EventPacket


def events(n: int) -> np.ndarray:
    return make_events(x=np.arange(n), y=np.arange(n) % 7, t=np.arange(n) * 10, p=np.arange(n) % 2)


def test_a_packet_is_its_events_and_compares_event_for_event():
    ev = events(5)
    packet = EventPacket(ev)
    assert len(packet) == 5 and np.asarray(packet) is ev
    assert packet == EventPacket(ev.copy()) and hash(packet) == hash(EventPacket(ev.copy()))
    changed = ev.copy()
    changed["p"][3] ^= 1
    assert packet != EventPacket(changed) and packet != EventPacket(ev[:4])
    assert packet != ev  # not an array: vector envs keep it as one object per env
    twin = pickle.loads(pickle.dumps(packet))
    assert twin == packet and twin.events.dtype == ev.dtype
    assert repr(packet) == "EventPacket(5 events, t 0..40 µs)"


def test_only_event_arrays_go_into_a_packet():
    with pytest.raises(TypeError, match="EVENT_DTYPE array, got float64"):
        EventPacket(np.zeros(3))
    with pytest.raises(TypeError, match="got list"):
        EventPacket([1, 2])
