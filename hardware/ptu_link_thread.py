"""The rig's PTU link: the FLIR driver behind one thin thread that steps the link's schedule.

:class:`PTULinkThread` steps the shared :class:`~wander_env.ptu.link.LinkSchedule` (the
simulator's scheduling of the same serial link: a queued target replaced by a newer one,
``PP`` then ``TP``, the position polls) in the time of its ``clock`` (``time.monotonic``,
or a replay's stream time when the rig serves it step by step), with every exchange run
through the :class:`~hardware.ptu_driver.FlirPTU` driver. :class:`hardware.rig_env.RigEnv`
hands it targets and reads polled positions; a failure halts the unit and is kept for
the env to raise.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from hardware.ptu_driver import FlirPTU, PTUError
from wander_env.ptu.link import LinkSchedule
from wander_env.ptu.units import positions_to_degrees, whole_position

__all__ = ["PTULinkThread"]


class PTULinkThread:
    """The rig's PTU link: the driver behind one thin thread that steps the shared
    :class:`~wander_env.ptu.link.LinkSchedule` (the sim's scheduling too) in the time of
    ``clock`` (``time.monotonic``): targets go in, polled positions come out.

    All serial traffic after start-up happens in the thread (:meth:`start`), each
    exchange in :meth:`serve`, so a caller never waits on the line. Positions are whole
    PTU positions (ints).
    """

    def __init__(
        self, ptu: FlirPTU, poll_s: float, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.ptu = ptu
        self.clock = clock
        self._res = ptu.resolution_arcsec
        self._cond = threading.Condition()
        self._stop = False
        start = self.to_positions(ptu.target())  # the unit's own state at start
        positions = self.to_positions(ptu.position())
        self.schedule = LinkSchedule(poll_s, start, clock())  # just polled above
        self.schedule.positions = positions
        self.error: PTUError | None = None
        self.halt_result = "not needed"
        self._thread = threading.Thread(target=self._run, name=f"rig-ptu-{ptu.url}", daemon=True)

    def start(self) -> None:
        """Start the thread that serves the line."""
        self._thread.start()

    # -- conversions --------------------------------------------------------------------

    def to_positions(self, deg: tuple[float, float]) -> tuple[int, int]:
        """(pan, tilt) degrees -> whole positions at the unit's resolution, as the driver
        sends them (:func:`~wander_env.ptu.units.whole_position`)."""
        return whole_position("pan", deg[0], self._res[0]), whole_position(
            "tilt", deg[1], self._res[1]
        )

    def to_degrees(self, pos: tuple[int, int]) -> tuple[float, float]:
        """(pan, tilt) positions -> degrees."""
        pan = positions_to_degrees(pos[0], self._res[0])
        return pan, positions_to_degrees(pos[1], self._res[1])

    # -- caller side ----------------------------------------------------------------------

    @property
    def counts(self) -> dict[str, int]:
        """Commands sent and replaced, polls."""
        with self._cond:
            return dict(self.schedule.counts)

    def command(self, target: tuple[int, int]) -> None:
        """Queue ``target`` (positions); replaces a queued one not yet sent."""
        with self._cond:
            self.schedule.submit(target, self.clock())
            self._cond.notify_all()

    def snapshot(self, target: tuple[int, int] | None = None) -> dict[str, Any]:
        """Positions of the last poll, the acknowledged target, the latest latency and,
        given a ``target``, whether the unit is still ``moving`` to it (one state: gaze
        and motion come from the same poll)."""
        with self._cond:
            s = self.schedule
            return {
                "positions": s.positions,
                "acked": s.acked,
                "latency_s": s.latency_s,
                "moving": None if target is None else s.moving(target),
            }

    def wait(self, target: tuple[int, int], timeout_s: float) -> bool:
        """Block until the unit rests on ``target`` (True), a fault, or the timeout (False)."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self.error is None and not self._stop:
                if not self.schedule.moving(target):
                    return True
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._cond.wait(remaining)
        return self.error is None

    def close(self) -> None:
        """Stop the thread (after the exchange in progress); the driver stays open."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(self.ptu.params.timeout_s + self.ptu.params.halt_timeout_s + 1.0)

    def halt_now(self) -> str:
        """Discard any queued target and halt (``H``) from the calling thread; the result
        is kept in ``halt_result`` (for ``metrics.json``)."""
        with self._cond:
            self.schedule.discard()
        result = self._halt()
        with self._cond:
            self.halt_result = result
        return result

    # -- the thread -----------------------------------------------------------------------

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._stop and (wait := self.schedule.due_s() - self.clock()) > 0:
                    self._cond.wait(wait)
                if self._stop:
                    return
            self.serve()
            if self.error is not None:
                return

    def serve(self) -> bool:
        """Run the exchange that is due now through the driver (``PP<n>``/``TP<n>``, or
        the ``PP``/``TP`` poll); False when none is due or the link has failed. A failure
        halts the unit and is kept in ``error`` (the env raises it)."""
        with self._cond:
            if self.error is not None or self.schedule.due_s() > self.clock():
                return False
            ex = self.schedule.begin(self.clock())
        try:
            if ex.is_poll:
                polled = self.to_positions(self.ptu.position())
            else:
                deg = {a: positions_to_degrees(v, self._res[a]) for a, v in ex.words}
                self.ptu.move_to(pan_deg=deg.get(0), tilt_deg=deg.get(1))
                polled = None
        except Exception as err:  # any failure ends the thread; the env raises it
            self._fail(err if isinstance(err, PTUError) else PTUError(f"{err!r}"))
            return False
        with self._cond:
            self.schedule.end(self.clock(), polled)
            self._cond.notify_all()
        return True

    def _fail(self, err: PTUError) -> None:
        halt = self._halt()
        with self._cond:
            self.error = err
            self.halt_result = halt
            self._cond.notify_all()

    def _halt(self) -> str:
        """Send ``H`` with the driver's halt timeout; says how it went (never raises)."""
        try:
            self.ptu.send("H", timeout_s=self.ptu.params.halt_timeout_s)
        except Exception as err:  # whatever the line does, the fault handler goes on
            logging.getLogger(__name__).warning("PTU %s: halt failed: %s", self.ptu.url, err)
            return f"halt (H) sent, not acknowledged: {err}"
        return "halt (H) acknowledged"
