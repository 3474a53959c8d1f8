"""Organized clouds straight from a depth image on the colour grid into CDR PointCloud2 bytes.

Layout as the RealSense ROS driver publishes ``/camera/depth/color/points`` with ordered clouds:
x, y, z float32 and ``rgb`` float32 holding packed b, g, r, a bytes; point_step 16; one point per
colour pixel, row by row; NaN where there is no depth. Each point is written straight into the
output message (``z * ray``, one compiled pass), with the header built once per size; the colour
stream is read as BGRA so that its pixels are the packed ``rgb`` field as they are.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from sofia_schemas import pointcloud
from sofia_schemas.cloud import XYZRGB_FIELDS, PointCloud2
from sofia_schemas.frames import CAMERA_FRAME

from .intrinsics import Intrinsics
from .shm import CloudBuffers

FRAME_ID = CAMERA_FRAME
POINT_STEP = 16


class CloudEncoder:
    """CDR PointCloud2 of (depth, colour) images of one size; rays and header cached per intrinsics."""

    def __init__(self, frame_id: str = FRAME_ID) -> None:
        self.frame_id = frame_id
        self._intrinsics: Intrinsics | None = None
        self._rays = np.zeros((0, 0, 2), np.float32)
        self._head = b""
        self._lut_units = 0.0  # the depth unit ``_lut`` was built for
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

    def metres(self, depth_units: np.ndarray, units_m: float) -> np.ndarray:
        """(H, W) float32 metres of a uint16 depth image in ``units_m`` (0, no depth, -> NaN), by lookup."""
        if units_m != self._lut_units:
            self._lut = np.arange(65536, dtype=np.float32) * np.float32(units_m)
            self._lut[0] = np.nan
            self._lut_units = units_m
        return np.take(self._lut, depth_units)

    def encode(
        self,
        z_m: np.ndarray,
        bgra: np.ndarray,
        intr: Intrinsics,
        stamp_ns: int,
        correct: Callable[[np.ndarray], np.ndarray] | None = None,
        buffers: CloudBuffers | None = None,
    ) -> Any:
        """CDR bytes of the organized cloud: a ``bytearray``, or with ``buffers`` what to put (a Zenoh
        shared-memory buffer the message was written into, see :class:`~sofia_camera.shm.CloudBuffers`).

        z_m: (H, W) float32 depth along the colour optical axis, metres, on the colour grid (NaN, inf or
        <= 0: no depth). bgra: (H, W, 4) uint8 colour image (librealsense ``bgra8``). intr: the colour
        intrinsics. correct: optional ``(n, 3) points_cam -> (n, 3)`` applied before writing (the
        calibration's depth correction).
        """
        self._prepare(intr)
        n = intr.width * intr.height
        head = bytearray(self._head)
        sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
        struct.pack_into("<iI", head, 4, sec, nsec)
        size = len(head) + n * POINT_STEP + 1
        if buffers is None:
            payload = bytearray(size)
            view = np.frombuffer(payload, np.uint8)
        else:
            view, payload = buffers.take(size)
        view[: len(head)] = np.frombuffer(head, np.uint8)
        body = view[len(head) : size - 1].reshape(n, POINT_STEP)
        z = np.ascontiguousarray(z_m, dtype=np.float32).reshape(n)
        colour = np.ascontiguousarray(bgra).view("<u4").reshape(n)
        if correct is None:
            missing = _write_points(z, self._rays, colour, body.view("<f4"), body.view("<u4"))
        else:
            z = np.where((z > 0) & (z < np.inf), z, np.float32(np.nan))
            points = np.stack([self._rays[0] * z, self._rays[1] * z, z], axis=-1)
            body.view("<f4")[:, :3] = correct(points)
            body.view("<u4")[:, 3] = colour
            missing = int(np.isnan(z).sum())
        view[size - 1] = 0 if missing else 1
        return payload if buffers is None else buffers.ready(payload)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _write_points(z, rays, colour, out_f32, out_u32):  # type: ignore[no-untyped-def]
    """Writes ``z * (x_n, y_n, 1)`` (NaN where no depth) and the packed colour into the (n, 4) point
    records; returns how many points have no depth."""
    missing = 0
    nan = np.float32(np.nan)
    for p in range(z.size):
        d = z[p]
        ok = (d > 0) & (d < np.inf)
        d = d if ok else nan
        missing += not ok
        out_f32[p, 0] = d * rays[0, p]
        out_f32[p, 1] = d * rays[1, p]
        out_f32[p, 2] = d
        out_u32[p, 3] = colour[p]
    return missing
