"""The robot's clock mapped onto the bus clock.

The robot stamps each state with its own time (ms since it booted). A state reaches us after a
varying delay, so ``received - robot_time`` is the clock offset plus that delay; the smallest
value over a sliding window is the best estimate of the offset (the least delayed state), and a
window lets it follow drift. A jump back of the robot's time (a restart) starts anew.

A state never counts as more than ``max_lag_ns`` late: when one is (the robot's clock runs slower
than ours, as franky-sim's on a busy machine, or a stall), the offset moves forward so that it is
stamped ``max_lag_ns`` before it was received; the next state that arrives on time moves it back.
"""

from __future__ import annotations

from collections import deque

WINDOW_NS = 2_000_000_000
MAX_LAG_NS = 5_000_000


class ClockMap:
    """Maps robot time (ns) to bus time (ns, ``time.time_ns`` of this host)."""

    def __init__(self, window_ns: int = WINDOW_NS, max_lag_ns: int = MAX_LAG_NS) -> None:
        self.window_ns = window_ns
        self.max_lag_ns = max_lag_ns
        self.lag_resets = 0
        self._offsets: deque[tuple[int, int]] = deque()  # (received_ns, offset_ns), offsets increasing
        self._last_robot_ns: int | None = None
        self._last_stamp: int | None = None
        self.resets = 0

    def update(self, robot_ns: int, received_ns: int) -> int:
        """Take one state (its robot time and when it was received) and return its bus time."""
        if self._last_robot_ns is not None and robot_ns < self._last_robot_ns:
            self._offsets.clear()
            self._last_stamp = None
            self.resets += 1
        self._last_robot_ns = robot_ns
        offset = received_ns - robot_ns
        # a monotonic deque: the front is the minimum of the window
        while self._offsets and self._offsets[-1][1] >= offset:
            self._offsets.pop()
        self._offsets.append((received_ns, offset))
        while self._offsets[0][0] < received_ns - self.window_ns:
            self._offsets.popleft()
        if offset - self._offsets[0][1] > self.max_lag_ns:  # late beyond any transport delay
            self._offsets.clear()
            self._offsets.append((received_ns, offset - self.max_lag_ns))
            self.lag_resets += 1
        stamp = robot_ns + self._offsets[0][1]
        if self._last_stamp is not None and stamp <= self._last_stamp:  # never back in time
            stamp = self._last_stamp + 1
        self._last_stamp = stamp
        return stamp
