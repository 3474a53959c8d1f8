"""A real RealSense camera through librealsense: discovery, opening its depth and colour sensors
at a mode, the visual preset, telemetry.

The sensors are streamed directly (not through ``rs.pipeline``) so that a real camera and the
software device share every step after the sensors (:class:`~sofia_camera.streams.SensorPair`).
Global time is switched off: frames keep the device's hardware timestamps, which the service maps
onto the bus clock itself.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import pyrealsense2 as rs

from .errors import BadOption, CameraUnavailable, UnsupportedMode
from .streams import FramePair, SensorPair

log = logging.getLogger(__name__)
PRESETS = (
    "default",
    "high_accuracy",
    "high_density",
    "medium_density",
    "hand",
    "custom",
    "remove_ir_pattern",
)
INFO = {"name": rs.camera_info.name, "serial": rs.camera_info.serial_number,
        "firmware": rs.camera_info.firmware_version, "usb_type": rs.camera_info.usb_type_descriptor,
        "product_line": rs.camera_info.product_line}  # fmt: skip


def device_info(dev: rs.device) -> dict[str, str]:
    """What the device tells about itself (fields it does not support are left out)."""
    return {k: str(dev.get_info(v)) for k, v in INFO.items() if dev.supports(v)}


def list_devices(context: rs.context | None = None) -> list[dict[str, str]]:
    """Connected RealSense cameras: name, serial, firmware, USB type."""
    return [device_info(d) for d in (context or rs.context()).query_devices()]


def _find_profile(
    sensor: Any, stream: rs.stream, fmt: rs.format, w: int, h: int, fps: int
) -> rs.stream_profile:
    for p in sensor.get_stream_profiles():
        if p.stream_type() == stream and p.format() == fmt and p.fps() == fps:
            v = p.as_video_stream_profile()
            if v.width() == w and v.height() == h:
                return p
    modes = sorted({f"{p.as_video_stream_profile().width()}x{p.as_video_stream_profile().height()}@{p.fps()}"
                    for p in sensor.get_stream_profiles() if p.stream_type() == stream})  # fmt: skip
    raise UnsupportedMode(w, h, fps, modes)


class DeviceCamera:
    """A connected D400 camera (``serial`` or the first found) streaming depth z16 + colour bgra8."""

    def __init__(
        self, serial: str | None, width: int, height: int, fps: int, preset: str | None = None
    ) -> None:
        if preset is not None and preset not in PRESETS:
            raise BadOption("--preset", preset, f"use one of {list(PRESETS)}")
        self.wanted = serial
        self.serial = serial or "?"
        self.mode = (width, height, fps)
        self.preset = preset
        self.device: rs.device | None = None
        self.depth_sensor: Any = None
        self.streams: SensorPair | None = None
        self._info: dict[str, str] = {}

    def _select(self) -> rs.device:
        devices = list(rs.context().query_devices())
        for dev in devices:
            if self.wanted is None or dev.get_info(rs.camera_info.serial_number) == self.wanted:
                return dev
        found = [d.get_info(rs.camera_info.serial_number) for d in devices]
        raise CameraUnavailable(
            f"no RealSense camera {self.wanted or ''} connected (found {found or 'none'})"
        )

    def open(self) -> None:
        if self.streams is not None:
            return
        try:
            dev = self._select()
            self._info = device_info(dev)
            self.serial = self._info.get("serial", self.serial)
            depth_sensor = dev.first_depth_sensor()
            color_sensor = dev.first_color_sensor()
            w, h, fps = self.mode
            depth_profile = _find_profile(depth_sensor, rs.stream.depth, rs.format.z16, w, h, fps)
            color_profile = _find_profile(color_sensor, rs.stream.color, rs.format.bgra8, w, h, fps)
            for sensor in (depth_sensor, color_sensor):
                if sensor.supports(rs.option.global_time_enabled):
                    sensor.set_option(rs.option.global_time_enabled, 0)
            if self.preset is not None and depth_sensor.supports(rs.option.visual_preset):
                depth_sensor.set_option(
                    rs.option.visual_preset, float(getattr(rs.rs400_visual_preset, self.preset))
                )
            streams = SensorPair(depth_sensor, depth_profile, color_sensor, color_profile)
            streams.start()
        except RuntimeError as e:  # librealsense reports a busy or vanished device this way
            raise CameraUnavailable(f"camera {self.wanted or ''}: {e}") from None
        self.device, self.depth_sensor, self.streams = dev, depth_sensor, streams
        log.info("streaming %s (%s) at %dx%d @ %d Hz", self._info.get("name"), self.serial, w, h, fps)

    def close(self) -> None:
        if self.streams is not None:
            self.streams.stop()
        self.streams = None
        self.device = None
        self.depth_sensor = None

    def wait_pair(self, timeout_s: float, max_skew_ms: float = 16.0) -> FramePair | None:
        if self.streams is None:
            time.sleep(timeout_s)
            return None
        return self.streams.wait_pair(timeout_s, max_skew_ms, time.time_ns)

    def bus_stamp_ns(self, depth: rs.frame) -> int | None:
        return None

    def info(self) -> dict[str, str]:
        return dict(self._info)

    def telemetry(self) -> dict[str, float]:
        out: dict[str, float] = {}
        sensor = self.depth_sensor
        if sensor is None:
            return out
        for name, option in (("asic_temperature_c", rs.option.asic_temperature),
                             ("projector_temperature_c", rs.option.projector_temperature)):  # fmt: skip
            try:
                if sensor.supports(option):
                    out[name] = round(float(sensor.get_option(option)), 1)
            except RuntimeError:  # unplugged between the check and the read
                pass
        return out
