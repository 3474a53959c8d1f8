"""When the replayer puts each message: its log time scaled by the rate, across loops.

The clock's origin is the first message played (wall time, log time). A loop continues the
previous loop's clock: its first message follows the previous loop's last by the loop's mean
message interval (:func:`loop_span_ns`), as a camera's next frame would, not at once (a burst of
two clouds makes a detector that keeps only the latest drop one). Behind schedule by more than
``RESYNC_LAG_S`` (a stalled subscriber, a stopped process), the clock restarts at the late message
instead of bursting to catch up.
"""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)

RESYNC_LAG_S = 0.5  # behind schedule by more than this: restart the clock instead of bursting
SINGLE_LOOP_NS = 1_000_000_000  # a loop whose messages share one log time repeats once a second


def loop_span_ns(first_ns: int | None, last_ns: int | None, n: int) -> int:
    """Log time (ns) from one loop's first message (``first_ns``) to the next loop's: the span to
    its last (``last_ns``) plus the mean interval of its ``n`` messages. A loop of one message, or
    all at one time, repeats once a second."""
    if first_ns is None or last_ns is None or n < 2 or last_ns <= first_ns:
        return SINGLE_LOOP_NS + (0 if first_ns is None or last_ns is None else last_ns - first_ns)
    span = last_ns - first_ns
    return span + span // (n - 1)


class PlayClock:
    """Seconds until each message is due, at ``rate`` times the recorded speed."""

    def __init__(self, rate: float) -> None:
        self.rate = rate
        self.anchor: tuple[float, int] | None = None  # (monotonic s, log ns) of the origin
        self.offset_ns = 0  # added to log times: the loops played before this one
        self.resyncs = 0  # restarts for being more than RESYNC_LAG_S behind

    def delay_s(self, log_time_ns: int, now_s: float) -> float:
        """Seconds from ``now_s`` (monotonic) until the message logged at ``log_time_ns`` is due
        (<= 0: now); the first message sets the origin, a late one restarts it."""
        t_ns = log_time_ns + self.offset_ns
        if self.anchor is None:
            self.anchor = (now_s, t_ns)
        due = self.anchor[0] + (t_ns - self.anchor[1]) / 1e9 / self.rate
        if now_s - due > RESYNC_LAG_S:
            self.resyncs += 1
            log.debug("%.2f s behind schedule, restarting the clock", now_s - due)
            self.anchor = (now_s, t_ns)
            return 0.0
        return due - now_s

    def next_loop(self, first_ns: int | None, last_ns: int | None, n: int) -> None:
        """The loop of ``n`` messages logged from ``first_ns`` to ``last_ns`` ended; the next
        continues its clock."""
        self.offset_ns += loop_span_ns(first_ns, last_ns, n)
