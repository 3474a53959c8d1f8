"""Depth and colour sensors streaming into frame queues, paired by timestamp.

A D435's depth and colour sensors are not hardware-synchronised: each frame carries its own
timestamp. :class:`SensorPair` takes each depth frame with the colour frame nearest in time and
reports their skew, so the service can say when they are not of the same instant.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Protocol

import pyrealsense2 as rs

log = logging.getLogger(__name__)
QUEUE_FRAMES = 4  # frames a queue keeps; older ones are dropped (and show up as frame-number gaps)
# Wall time a depth frame waits for the colour frame of its instant: the sensors deliver on their own
# threads, and a loaded host delays one more than the other (the skew itself is in device time)
COLOR_WAIT_S = 0.1


@dataclass
class FramePair:
    """A depth frame and the colour frame nearest in time (None when no colour arrived).

    skew_ms: colour timestamp - depth timestamp (device clock, ms); 0 without colour.
    arrival_ns: bus-clock time the depth frame was taken from its queue.
    """

    depth: rs.depth_frame
    color: rs.video_frame | None
    skew_ms: float
    arrival_ns: int


class FrameSource(Protocol):
    """A camera the service streams from: a real D435 or a software device."""

    serial: str

    def open(self) -> None:
        """Start streaming; raises CameraUnavailable when the camera cannot be opened now."""

    def close(self) -> None:
        """Stop streaming (safe to call when not open or after an unplug)."""

    def wait_pair(self, timeout_s: float, max_skew_ms: float = 16.0) -> FramePair | None:
        """The next depth frame with the colour frame nearest in time (waiting up to ``COLOR_WAIT_S``
        for one within ``max_skew_ms``), or None after ``timeout_s`` without depth."""

    def bus_stamp_ns(self, depth: rs.frame) -> int | None:
        """The frame's bus time when the source knows it exactly (simulation), else None."""

    def info(self) -> dict[str, str]:
        """Name, serial, firmware, USB type (what is known)."""

    def telemetry(self) -> dict[str, float]:
        """Live readings (temperatures) when the camera has them."""


class SensorPair:
    """Streams ``depth_profile`` of ``depth_sensor`` and ``color_profile`` of ``color_sensor``."""

    def __init__(self, depth_sensor: Any, depth_profile: rs.stream_profile, color_sensor: Any,
                 color_profile: rs.stream_profile) -> None:  # fmt: skip
        self.sensors = ((depth_sensor, depth_profile), (color_sensor, color_profile))
        self.depth_queue = rs.frame_queue(QUEUE_FRAMES, keep_frames=True)
        self.color_queue = rs.frame_queue(QUEUE_FRAMES, keep_frames=True)
        self.colors: deque[rs.frame] = deque(maxlen=QUEUE_FRAMES)
        self.fps = depth_profile.fps()
        self.started = False

    def start(self) -> None:
        for (sensor, profile), queue in zip(self.sensors, (self.depth_queue, self.color_queue), strict=True):
            sensor.open(profile)
            sensor.start(queue)
        self.started = True

    def stop(self) -> None:
        if not self.started:
            return
        self.started = False
        for sensor, _ in self.sensors:
            for action in (sensor.stop, sensor.close):
                try:
                    action()
                except RuntimeError as e:  # already stopped, or the device is gone
                    log.debug("%s: %s", action.__name__, e)
        self.colors.clear()

    def _drain_colors(self) -> None:
        while True:
            ok, frame = self.color_queue.try_wait_for_frame(0)
            if not ok:
                return
            self.colors.append(frame)

    def _nearest(self, t_ms: float) -> tuple[rs.frame | None, float]:
        if not self.colors:
            return None, 0.0
        best = min(self.colors, key=lambda c: abs(c.get_timestamp() - t_ms))
        return best, best.get_timestamp() - t_ms

    def wait_pair(self, timeout_s: float, max_skew_ms: float, arrival_ns: Any) -> FramePair | None:
        """Next depth frame and the nearest colour; waits up to ``COLOR_WAIT_S`` (wall time) for a
        colour frame within ``max_skew_ms`` (device time) of it, unless a later colour frame already
        came. ``arrival_ns``: the bus clock (called when the depth frame is taken)."""
        ok, depth = self.depth_queue.try_wait_for_frame(int(timeout_s * 1000))
        if not ok:
            return None
        arrived = int(arrival_ns())
        t_ms = depth.get_timestamp()
        self._drain_colors()
        color, skew = self._nearest(t_ms)
        deadline = time.monotonic() + COLOR_WAIT_S
        while color is None or (abs(skew) > max_skew_ms and self.colors[-1].get_timestamp() < t_ms):
            ok, frame = self.color_queue.try_wait_for_frame(max(1, int(1000 * (deadline - time.monotonic()))))
            if not ok:
                break
            self.colors.append(frame)
            self._drain_colors()
            color, skew = self._nearest(t_ms)
        if color is not None:  # colour frames older than the one used will not be wanted again
            while self.colors and self.colors[0].get_timestamp() < color.get_timestamp():
                self.colors.popleft()
        return FramePair(depth.as_depth_frame(), color.as_video_frame() if color else None, skew, arrived)


STOP_POLL_S = 0.25  # frames are waited for in slices this long, so a stop is seen within one


def wait_pair(source: FrameSource, timeout: float, max_skew_ms: float, stop: Any) -> FramePair | None:
    """The next frame pair of ``source`` within ``timeout`` s, waited for in slices of
    ``STOP_POLL_S`` so that a set ``stop`` event (SIGTERM) ends the wait within a slice (None on
    timeout or stop)."""
    deadline = time.monotonic() + timeout
    while not stop.is_set():
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return None
        pair = source.wait_pair(min(remaining, STOP_POLL_S), max_skew_ms)
        if pair is not None:
            return pair
    return None
