"""The camera's clock mapped onto the bus clock (wall-clock integer nanoseconds, ``now_ns``).

Frames stamped by the device's hardware clock (ms since the camera started) are mapped with an
offset estimated online as the smallest ``arrival - device time`` over a sliding window: the
frame that reached us fastest bounds the transport delay, so a mapped stamp is never later than
the frame's arrival. A device clock that jumps back (a reconnected or reset camera) starts a new
estimate.
"""

from __future__ import annotations

from collections import deque

import pyrealsense2 as rs

WINDOW = 300  # frames (10 s at 30 Hz)
JUMP_BACK_MS = 1000.0


class ClockMap:
    """Device milliseconds -> bus nanoseconds."""

    def __init__(self, window: int = WINDOW) -> None:
        self._offsets: deque[int] = deque(maxlen=window)
        self._last_device_ms: float | None = None
        self.resets = 0

    def reset(self) -> None:
        self._offsets.clear()
        self._last_device_ms = None

    def map(self, device_ms: float, arrival_ns: int) -> int:
        """Bus time of a frame stamped ``device_ms`` by the camera that arrived at ``arrival_ns``."""
        if self._last_device_ms is not None and device_ms < self._last_device_ms - JUMP_BACK_MS:
            self.reset()
            self.resets += 1
        self._last_device_ms = device_ms
        device_ns = round(device_ms * 1e6)
        self._offsets.append(arrival_ns - device_ns)
        return device_ns + min(self._offsets)

    def stamp(self, frame: rs.frame, arrival_ns: int) -> int:
        """Bus stamp of ``frame`` by its timestamp domain: the hardware clock is mapped; system and
        global time are already host wall-clock milliseconds."""
        t_ms = frame.get_timestamp()
        if frame.get_frame_timestamp_domain() == rs.timestamp_domain.hardware_clock:
            return self.map(t_ms, arrival_ns)
        return round(t_ms * 1e6)
