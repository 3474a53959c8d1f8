"""Organized clouds straight from an aligned depth image into CDR PointCloud2 bytes.

Layout as the RealSense ROS driver publishes ``/camera/depth/color/points`` with ordered clouds:
x, y, z float32 and ``rgb`` float32 holding packed b, g, r, a bytes; point_step 16; one point per
colour pixel, row by row; NaN where there is no depth. Each coordinate is computed straight into
the output message (``z * ray``), with the header built once per size; the colour stream is read
as BGRA so that its pixels are the packed ``rgb`` field as they are.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

import numpy as np
from sofia_schemas import pointcloud
from sofia_schemas.cloud import XYZRGB_FIELDS, PointCloud2

from .intrinsics import Intrinsics

FRAME_ID = "camera_color_optical_frame"
POINT_STEP = 16


class CloudEncoder:
    """CDR PointCloud2 of (depth, colour) images of one size; rays and header cached per intrinsics."""

    def __init__(self, frame_id: str = FRAME_ID) -> None:
        self.frame_id = frame_id
        self._intrinsics: Intrinsics | None = None
        self._rays = np.zeros((0, 0, 2), np.float32)
        self._head = b""
        self._lut_units = 0.0
        self._lut = np.zeros(65536, np.float32)

    def _prepare(self, intr: Intrinsics) -> None:
        if intr == self._intrinsics:
            return
        h, w = intr.height, intr.width
        rays = intr.rays()
        self._rays = np.ascontiguousarray(rays.reshape(-1, 2).T)  # (2, n): x_n row, y_n row
        n_data = h * w * POINT_STEP
        template = PointCloud2(
            0, self.frame_id, h, w, XYZRGB_FIELDS, POINT_STEP, POINT_STEP * w, bytes(n_data)
        )
        self._head = pointcloud.encode(template)[: -n_data - 1]
        self._intrinsics = intr

    def encode(
        self,
        depth_units: np.ndarray,
        units_m: float,
        bgra: np.ndarray,
        intr: Intrinsics,
        stamp_ns: int,
        correct: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> bytearray:
        """CDR bytes of the organized cloud.

        depth_units: (H, W) uint16 aligned depth in ``units_m`` metres (0 = no depth). bgra: (H, W, 4)
        uint8 colour image (librealsense ``bgra8``). intr: the colour intrinsics (the aligned depth's). correct: optional
        ``(n, 3) points_cam -> (n, 3)`` applied before writing (the calibration's depth correction).
        """
        self._prepare(intr)
        n = intr.width * intr.height
        head = bytearray(self._head)
        sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
        struct.pack_into("<iI", head, 4, sec, nsec)
        out = bytearray(len(head) + n * POINT_STEP + 1)
        out[: len(head)] = head
        body = np.frombuffer(out, dtype=np.uint8, count=n * POINT_STEP, offset=len(head)).reshape(
            n, POINT_STEP
        )
        xyz = body.view("<f4")[:, :3]
        if units_m != self._lut_units:  # depth unit -> metres, 0 (no depth) -> NaN, in one lookup
            self._lut = np.arange(65536, dtype=np.float32) * np.float32(units_m)
            self._lut[0] = np.nan
            self._lut_units = units_m
        z = self._lut[depth_units.reshape(n)]
        if correct is None:
            np.multiply(self._rays[0], z, out=xyz[:, 0])
            np.multiply(self._rays[1], z, out=xyz[:, 1])
            xyz[:, 2] = z
        else:
            points = np.stack([self._rays[0] * z, self._rays[1] * z, z], axis=-1)
            xyz[:] = correct(points)
        body.view("<u4")[:, 3] = np.ascontiguousarray(bgra).view("<u4").reshape(n)
        out[-1] = 0 if (depth_units == 0).any() else 1
        return out
