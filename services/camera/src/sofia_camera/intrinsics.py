"""Pinhole intrinsics of the depth and colour streams, the D435's modes, and vectorised deprojection.

Pixel convention of librealsense: pixel ``(u, v)`` (column, row) has its centre at integer
coordinates; a camera-frame point is ``p_cam = z * (x_n, y_n, 1)`` with ``(x_n, y_n)`` the
undistorted normalised coordinates of the pixel. Frames: optical (x right, y down, z forward).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pyrealsense2 as rs

from .errors import UnsupportedIntrinsics, UnsupportedMode

FPS = 30
# (width, height) -> (depth fx = fy, colour fx = fy): the nominal D435 values (a real camera
# reports its own factory calibration, read from the device).
D435_MODES: dict[tuple[int, int], tuple[float, float]] = {
    (640, 480): (383.0, 615.0),
    (848, 480): (421.0, 610.0),
    (1280, 720): (638.0, 920.0),
}
# colour optical frame <- depth (left imager) optical frame: the D435's colour camera sits 15 mm
# beside the left imager (p_color = T_color_depth @ p_depth)
T_COLOR_DEPTH_D435 = np.array(
    [[1.0, 0.0, 0.0, 0.015], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
DEPTH_UNITS_M = 0.001  # the D435's default depth unit


@dataclass(frozen=True)
class Intrinsics:
    """One stream's intrinsics (librealsense ``rs2_intrinsics``)."""

    width: int
    height: int
    fx: float
    fy: float
    ppx: float
    ppy: float
    model: str = "none"  # none | brown_conrady | inverse_brown_conrady | ...
    coeffs: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def from_rs(cls, i: rs.intrinsics) -> Intrinsics:
        c = [float(v) for v in i.coeffs]
        return cls(int(i.width), int(i.height), float(i.fx), float(i.fy), float(i.ppx), float(i.ppy),
                   str(i.model).split(".")[-1], (c[0], c[1], c[2], c[3], c[4]))  # fmt: skip

    def to_rs(self) -> rs.intrinsics:
        i = rs.intrinsics()
        i.width, i.height, i.fx, i.fy, i.ppx, i.ppy = (
            self.width,
            self.height,
            self.fx,
            self.fy,
            self.ppx,
            self.ppy,
        )
        i.model = getattr(rs.distortion, self.model)
        i.coeffs = list(self.coeffs)
        return i

    @property
    def K(self) -> np.ndarray:
        """(3, 3) camera matrix."""
        return np.array([[self.fx, 0.0, self.ppx], [0.0, self.fy, self.ppy], [0.0, 0.0, 1.0]])

    def rays(self) -> np.ndarray:
        """(H, W, 2) float32 ``(x_n, y_n)``: the point of pixel (u, v) at depth z is ``z * (x_n, y_n, 1)``.

        Vectorised ``rs2_deproject_pixel_to_point`` for every pixel (same models, same iterations)."""
        u, v = np.meshgrid(np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64))
        return self.normalized(u, v).astype(np.float32)

    def normalized(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(..., 2) float64 ``(x_n, y_n)`` of pixel coordinates ``u`` (column), ``v`` (row), arrays of one
        shape (any real coordinates: ``u - 0.5`` is a pixel's left edge)."""
        x = (u - self.ppx) / self.fx
        y = (v - self.ppy) / self.fy
        k1, k2, p1, p2, k3 = self.coeffs
        if self.model == "none" or not any(self.coeffs):
            pass
        elif self.model in ("brown_conrady", "inverse_brown_conrady"):
            xd, yd = x, y  # undistort by fixed-point iteration, as librealsense does
            for _ in range(10):
                r2 = x * x + y * y
                icdist = 1 / (1 + ((k3 * r2 + k2) * r2 + k1) * r2)
                dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
                dy = 2 * p2 * x * y + p1 * (r2 + 2 * y * y)
                x, y = (xd - dx) * icdist, (yd - dy) * icdist
        else:
            raise UnsupportedIntrinsics(self.model)
        return np.stack([x, y], axis=-1)


@dataclass(frozen=True)
class StreamSpec:
    """The two streams of a camera mode: depth (left imager) and colour, and how they sit.

    T_color_depth: (4, 4) colour optical frame <- depth optical frame, metres.
    """

    depth: Intrinsics
    color: Intrinsics
    fps: int = FPS
    T_color_depth: np.ndarray = field(default_factory=lambda: T_COLOR_DEPTH_D435.copy())
    depth_units: float = DEPTH_UNITS_M

    @property
    def size(self) -> tuple[int, int]:
        return self.color.width, self.color.height


def d435_spec(width: int = 640, height: int = 480, fps: int = FPS) -> StreamSpec:
    """The nominal D435 streams of a mode (640x480, 848x480 or 1280x720), principal points centred."""
    if (width, height) not in D435_MODES or fps not in (6, 15, 30):
        raise UnsupportedMode(width, height, fps, [f"{w}x{h} @ 6/15/30" for w, h in D435_MODES])
    f_depth, f_color = D435_MODES[(width, height)]
    cx, cy = (width - 1) / 2, (height - 1) / 2
    return StreamSpec(
        depth=Intrinsics(width, height, f_depth, f_depth, cx, cy),
        color=Intrinsics(width, height, f_color, f_color, cx, cy),
        fps=fps,
    )
