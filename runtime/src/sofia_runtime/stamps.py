"""Stamp checks shared by the services: a stamp too far in the future (or, where asked, older
than a start time) is refused with :class:`StampRefused` and counted.

A message stamped in the future would otherwise win every "newest wins" comparison until the clock
catches up (a calibration result stamped ``2**62`` ns pins the detector's ``T_flange_cam`` for
a century). Stamps are integer nanoseconds of the wall clock (:func:`sofia_schemas.messages.now_ns`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from sofia_schemas.errors import SofiaError
from sofia_schemas.messages import now_ns

FUTURE_TOLERANCE_NS = 2_000_000_000  # 2 s: hosts kept by NTP/PTP agree far better; more is a bad clock


def _seconds(delta_ns: int) -> str:
    """``delta_ns`` in seconds, 4 significant digits; any integer (10**400 included)."""
    return f"{delta_ns / 1e9:.4g}" if abs(delta_ns) < 10**300 else f"about 10**{len(str(abs(delta_ns))) - 10}"


def _shown(stamp_ns: int) -> str:
    text = str(stamp_ns)
    return text if len(text) <= 24 else f"{text[:12]}... ({len(text)} digits)"


class StampRefused(SofiaError, ValueError):  # noqa: N818 - named as in STYLE.md
    """A message's stamp is outside the accepted window."""

    def __init__(self, what: str, stamp_ns: int, reason: str) -> None:
        super().__init__(f"{what} refused: stamp_ns {_shown(stamp_ns)} is {reason}")
        self.stamp_ns = stamp_ns


class StampCheck:
    """Checks stamps against the wall clock: at most ``future_tolerance_ns`` ahead of it and, when
    asked (``since_start=True``), not before ``start_ns`` (default: when this check was made).
    ``counters``: ``future_stamps`` and ``stamps_before_start`` refused so far. Thread-safe."""

    def __init__(self, future_tolerance_ns: int = FUTURE_TOLERANCE_NS, start_ns: int | None = None,
                 clock: Callable[[], int] = now_ns) -> None:  # fmt: skip
        if future_tolerance_ns < 0:
            raise ValueError(f"future_tolerance_ns must be >= 0, got {future_tolerance_ns}")
        self.clock = clock
        self.future_tolerance_ns = future_tolerance_ns
        self.start_ns = clock() if start_ns is None else start_ns
        self.counters = {"future_stamps": 0, "stamps_before_start": 0}
        self._lock = threading.Lock()

    def check(self, what: str, stamp_ns: int, since_start: bool = False) -> int:
        """``stamp_ns`` if accepted; raises :class:`StampRefused` (and counts it) otherwise."""
        now = self.clock()
        if stamp_ns > now + self.future_tolerance_ns:
            self._count("future_stamps")
            ahead = (
                f"{_seconds(stamp_ns - now)} s in the future (tolerance {self.future_tolerance_ns / 1e9:g} s)"
            )
            raise StampRefused(what, stamp_ns, ahead)
        if since_start and stamp_ns < self.start_ns:
            self._count("stamps_before_start")
            before = f"{_seconds(self.start_ns - stamp_ns)} s before this service started"
            raise StampRefused(what, stamp_ns, before)
        return stamp_ns

    def _count(self, name: str) -> None:
        with self._lock:
            self.counters[name] += 1
