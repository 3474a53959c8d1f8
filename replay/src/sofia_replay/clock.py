"""When the replayer puts each message: its log time scaled by the rate, across loops.

The clock's origin is the first message played (wall time, log time). A loop continues the
previous loop's clock: each topic's first message follows its last by the topic's mean interval
(:func:`loop_span_ns`), as a camera's next frame would, not at once (a burst of two clouds makes a
detector that keeps only the latest drop one). Behind schedule by more than
``RESYNC_LAG_S`` (a stalled subscriber, a stopped process), the clock restarts at the late message
instead of bursting to catch up.
"""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)

RESYNC_LAG_S = 0.5  # behind schedule by more than this: restart the clock instead of bursting
SINGLE_LOOP_NS = 1_000_000_000  # a loop whose messages share one log time repeats once a second


def loop_span_ns(topics: dict[str, tuple[int, int, int]]) -> int:
    """Log time (ns) from one loop's start to the next's, from each topic's (first log time, last
    log time, count) in the loop. Each topic's next first message follows its last by its mean
    interval (a 30 Hz camera's first cloud one period after its last): the longest such loop of
    the topics with two or more messages at different times, so that no topic bursts, and at least
    until just after this loop's last message. A loop whose messages all share one time repeats
    once a second."""
    if not topics:
        return SINGLE_LOOP_NS
    first = min(f for f, _, _ in topics.values())
    last = max(la for _, la, _ in topics.values())
    periodic = [(la - f) * n // (n - 1) for f, la, n in topics.values() if n >= 2 and la > f]
    if not periodic:
        return SINGLE_LOOP_NS + last - first
    return max(*periodic, last - first + 1)


class PlayClock:
    """Seconds until each message is due, at ``rate`` times the recorded speed."""

    def __init__(self, rate: float) -> None:
        self.rate = rate
        self.anchor: tuple[float, int] | None = None  # (monotonic s, log ns) of the origin
        self.offset_ns = 0  # added to log times: the loops played before this one
        self.resyncs = 0  # restarts for being more than RESYNC_LAG_S behind
        self._topics: dict[str, tuple[int, int, int]] = {}  # this loop's (first, last, count) per topic

    def delay_s(self, topic: str, log_time_ns: int, now_s: float) -> float:
        """Seconds from ``now_s`` (monotonic) until the message of ``topic`` logged at
        ``log_time_ns`` is due (<= 0: now); the first message sets the origin, a late one restarts
        it."""
        self._played(topic, log_time_ns)
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

    def _played(self, topic: str, log_time_ns: int) -> None:
        """Count a message of this loop in its topic's (first, last, count)."""
        f, _, n = self._topics.get(topic, (log_time_ns, 0, 0))
        self._topics[topic] = (f, log_time_ns, n + 1)

    def next_loop(self) -> None:
        """This loop ended; the next one continues its clock (:func:`loop_span_ns`)."""
        self.offset_ns += loop_span_ns(self._topics)
        self._topics = {}
