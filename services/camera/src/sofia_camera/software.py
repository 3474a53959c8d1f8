"""A D435 made of librealsense's software device: frames rendered elsewhere (the simulator, tests)
are injected into librealsense and come out of it exactly as a real camera's would (profiles,
intrinsics, extrinsics, depth units, timestamps), so the service's whole librealsense path runs.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict

import numpy as np
import pyrealsense2 as rs

from .errors import CameraUnavailable
from .intrinsics import StreamSpec, d435_spec
from .streams import FramePair, SensorPair

SIM_SERIAL = "SIM-D435"


def _profile(sensor: rs.software_sensor, stream: rs.stream, uid: int, spec: StreamSpec) -> rs.stream_profile:
    depth = stream == rs.stream.depth
    intr = spec.depth if depth else spec.color
    vs = rs.video_stream()
    vs.type, vs.index, vs.uid = stream, 0, uid
    vs.width, vs.height, vs.fps = intr.width, intr.height, spec.fps
    vs.bpp = 2 if depth else 4
    vs.fmt = rs.format.z16 if depth else rs.format.bgra8
    vs.intrinsics = intr.to_rs()
    return sensor.add_video_stream(vs)


class SoftwareCamera:
    """A software-device D435 of ``spec`` (default: 640x480 @ 30 Hz nominal D435 streams).

    ``inject`` pushes one depth + colour frame; ``unplug`` stops the device's sensors as a pulled
    cable would (the service then sees no frames and cannot reopen it until ``replug``).
    """

    def __init__(self, spec: StreamSpec | None = None, serial: str = SIM_SERIAL) -> None:
        self.spec = spec or d435_spec()
        self.serial = serial
        self.device = rs.software_device()
        for key, value in ((rs.camera_info.name, "Intel RealSense D435 (software device)"),
                           (rs.camera_info.serial_number, serial), (rs.camera_info.firmware_version, "software"),
                           (rs.camera_info.usb_type_descriptor, "none")):  # fmt: skip
            self.device.register_info(key, value)
        self.depth_sensor = self.device.add_sensor("Stereo Module")
        self.color_sensor = self.device.add_sensor("RGB Camera")
        self.depth_profile = _profile(self.depth_sensor, rs.stream.depth, 0, self.spec)
        self.color_profile = _profile(self.color_sensor, rs.stream.color, 1, self.spec)
        self.depth_sensor.add_read_only_option(rs.option.depth_units, self.spec.depth_units)
        ex = rs.extrinsics()
        T = self.spec.T_color_depth
        ex.rotation = [float(v) for v in T[:3, :3].T.ravel()]  # librealsense: column-major
        ex.translation = [float(v) for v in T[:3, 3]]
        self.depth_profile.register_extrinsics_to(self.color_profile, ex)
        self.plugged = True
        self.streams: SensorPair | None = None
        self.frame_number = 0
        self._stamps: OrderedDict[int, int] = OrderedDict()
        self._lock = threading.Lock()

    # --- FrameSource ------------------------------------------------------
    def open(self) -> None:
        with self._lock:
            if not self.plugged:
                raise CameraUnavailable(f"software camera {self.serial} is unplugged")
            if self.streams is None:
                self.streams = SensorPair(
                    self.depth_sensor, self.depth_profile, self.color_sensor, self.color_profile
                )
                self.streams.start()

    def close(self) -> None:
        with self._lock:
            if self.streams is not None:
                self.streams.stop()
                self.streams = None

    def wait_pair(self, timeout_s: float, max_skew_ms: float = 16.0) -> FramePair | None:
        streams = self.streams
        if streams is None:
            time.sleep(timeout_s)
            return None
        return streams.wait_pair(timeout_s, max_skew_ms, time.time_ns)

    def bus_stamp_ns(self, depth: rs.frame) -> int | None:
        with self._lock:
            return self._stamps.get(depth.get_frame_number())

    def info(self) -> dict[str, str]:
        return {"name": "Intel RealSense D435 (software device)", "serial": self.serial,
                "firmware": "software", "usb_type": "none"}  # fmt: skip

    def telemetry(self) -> dict[str, float]:
        return {}

    # --- the other side of the cable ---------------------------------------
    def unplug(self) -> None:
        """Stop the software device's sensors, as a pulled USB cable stops a D435."""
        with self._lock:
            self.plugged = False
            if self.streams is not None:
                self.streams.stop()

    def replug(self) -> None:
        with self._lock:
            self.plugged = True

    def inject(self, depth_m: np.ndarray, rgb: np.ndarray, device_time_ms: float,
               color_time_ms: float | None = None, stamp_ns: int | None = None) -> int:  # fmt: skip
        """Push one frame of each stream; returns its frame number (dropped silently when not streaming).

        depth_m: (H, W) depth-imager depth along its optical axis, metres; NaN, inf or <= 0 for no depth.
        rgb: (H, W, 3) uint8 colour image. device_time_ms: the camera's hardware clock (depth frame);
        color_time_ms: the colour frame's (default: the same instant). stamp_ns: the frame's exact bus
        time when known (simulation: the flange pose's stamp), reported by :meth:`bus_stamp_ns`.
        """
        spec = self.spec
        depth_m = np.asarray(depth_m, dtype=np.float64)
        if depth_m.shape != (spec.depth.height, spec.depth.width):
            raise ValueError(f"depth must be {spec.depth.height}x{spec.depth.width}, got {depth_m.shape}")
        if rgb.shape != (spec.color.height, spec.color.width, 3) or rgb.dtype != np.uint8:
            raise ValueError(
                f"rgb must be uint8 ({spec.color.height}, {spec.color.width}, 3), got {rgb.dtype} {rgb.shape}"
            )
        bgra = np.empty((*rgb.shape[:2], 4), np.uint8)
        bgra[..., :3] = rgb[..., ::-1]
        bgra[..., 3] = 255
        units = np.where(np.isfinite(depth_m) & (depth_m > 0), depth_m / spec.depth_units, 0.0)
        z16 = np.ascontiguousarray(np.clip(np.round(units), 0, 65535).astype(np.uint16))
        with self._lock:
            self.frame_number += 1
            number = self.frame_number
            if stamp_ns is not None:
                self._stamps[number] = int(stamp_ns)
                while len(self._stamps) > 64:
                    self._stamps.popitem(last=False)
            if self.streams is None or not self.plugged:
                return number
            for sensor, profile, pixels, bpp, t_ms in (
                (self.depth_sensor, self.depth_profile, z16, 2, device_time_ms),
                (self.color_sensor, self.color_profile, bgra, 4,
                 device_time_ms if color_time_ms is None else color_time_ms),
            ):  # fmt: skip
                frame = rs.software_video_frame()
                frame.pixels = pixels
                frame.bpp = bpp
                frame.stride = pixels.shape[1] * bpp
                frame.timestamp = float(t_ms)
                frame.domain = rs.timestamp_domain.hardware_clock
                frame.frame_number = number
                frame.profile = profile.as_video_stream_profile()
                if bpp == 2:
                    frame.depth_units = spec.depth_units
                sensor.on_video_frame(frame)
        return number
