"""Depth registered onto the colour grid: the depth image's points moved into the colour camera and
z-buffered per colour pixel, in one compiled pass over the depth rows (the work ``rs.align(color)``
does, for the organized cloud on the colour grid).

Each depth pixel covers the box between its edges (u +- 0.5, v +- 0.5). An edge is deprojected with
the depth intrinsics (``rs2_deproject_pixel_to_point`` rays, precomputed per geometry), moved by the
depth -> colour extrinsics and projected with the colour intrinsics (``rs2_project_point_to_pixel``);
every colour pixel whose centre lies in the half-open box gets the pixel's colour-frame z, the
nearest one winning. Two neighbours on one surface project their common edge at their mean depth, so
their boxes meet exactly: each colour pixel takes one depth pixel. Where they are not one surface (a
depth step, or a neighbour without depth), each side projects the edge at its own depth and reaches
half a colour pixel beyond it, as ``rs.align``'s rounded boxes do (same coverage of holes and edges).

``rs.align`` rounds every box outwards, so a colour pixel on the border of two depth pixels of one
surface takes the smaller of their depths: its clouds come out short on average (about 0.6 mm at
0.5 m with the D435's noise); neighbouring boxes do not overlap here. The stored value is z in the
colour frame (``rs.align`` keeps the depth frame's z, off by the extrinsics' rotation and z offset).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import numpy.typing as npt
import pyrealsense2 as rs

from .errors import UnsupportedIntrinsics
from .intrinsics import Intrinsics

# colour-camera lens models ``project`` knows (librealsense ``rs2_project_point_to_pixel``)
_MODELS = {"none": 0, "modified_brown_conrady": 1, "inverse_brown_conrady": 1, "brown_conrady": 2}


def extrinsics_matrix(ex: rs.extrinsics) -> np.ndarray:
    """(4, 4) T_to_from of a librealsense ``rs2_extrinsics`` (rotation stored column-major)."""
    T = np.eye(4)
    T[:3, :3] = np.array(ex.rotation, dtype=np.float64).reshape(3, 3).T
    T[:3, 3] = ex.translation
    return T


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _to_pixel(z, ax, ay, az, t, cam, k):  # type: ignore[no-untyped-def]
    """Colour pixel coordinates (u, v) of ``z * a + t`` (``rs2_project_point_to_pixel``); ``k``: the
    lens model's number (``_MODELS``) and its 5 coefficients, None without distortion (the branch is
    then compiled out)."""
    pz = z * az + t[2]
    x, y = (z * ax + t[0]) / pz, (z * ay + t[1]) / pz
    if k is not None:
        r2 = x * x + y * y
        f = 1 + k[1] * r2 + k[2] * r2 * r2 + k[5] * r2 * r2 * r2
        xf, yf = x * f, y * f
        if k[0] == 1:  # modified/inverse Brown-Conrady: tangential terms on the radially distorted point
            x, y = xf, yf
        x, y = (
            xf + 2 * k[3] * x * y + k[4] * (r2 + 2 * x * x),
            yf + 2 * k[4] * x * y + k[3] * (r2 + 2 * y * y),
        )
    return x * cam[0] + cam[2], y * cam[1] + cam[3]


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _first(c, n):  # type: ignore[no-untyped-def]
    """Index of the first pixel centre at or after coordinate ``c`` (NaN: none), clamped to [0, n]."""
    return np.int32(np.ceil(min(max(c, np.float32(0)), np.float32(n)))) if c == c else np.int32(n)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _edge_depths(za, zb, thr):  # type: ignore[no-untyped-def]
    """How the edge between two neighbouring depth pixels is projected, seen from each side: at their
    mean depth when both have depth on one surface (their colour boxes meet exactly), else each at its
    own depth and pushed half a colour pixel outwards (the box reaches into a neighbour without depth
    or behind it, as ``rs.align``'s rounded boxes do; the z-buffer keeps the nearer surface)."""
    same = (za > 0) & (zb > 0) & (abs(za - zb) <= thr * (za + zb))
    m = np.float32(0.5) * (za + zb)
    one = np.float32(1)
    pad = np.float32(0) if same else np.float32(0.5)
    return (m if same else (za if za > 0 else one)), (m if same else (zb if zb > 0 else one)), pad


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _load_row(depth, y, units, row):  # type: ignore[no-untyped-def]
    """Row ``y`` of the depth image in metres into ``row[1:-1]`` (zeros outside the image)."""
    if 0 <= y < depth.shape[0]:
        for x in range(depth.shape[1]):
            row[x + 1] = depth[y, x] * units
    else:
        row[:] = 0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _rays_row(xs, y, R, grid, row, out):  # type: ignore[no-untyped-def]
    """``out`` (3, n): R @ (x_n, y_n, 1) along one row, from separable coordinates (``grid`` None: no
    depth lens distortion) or the row ``row`` of the (3, rows, n) ``grid``."""
    if grid is None:
        for c in range(3):
            for x in range(xs.size):
                out[c, x] = R[c, 0] * xs[x] + R[c, 1] * y + R[c, 2]
    else:
        out[:] = grid[:, row, :]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _register_rows(depth, units, y0, y1, axes, R, grids, t, cam, k, thr, slack, z_color):  # type: ignore[no-untyped-def]
    """Depth rows ``y0 .. y1 - 1`` scattered into ``z_color`` (filled with +inf first)."""
    x_edges, x_centres, y_edges, y_centres = axes
    g_vertical, g_horizontal, g_centre = grids
    w = depth.shape[1]
    h_c, w_c = z_color.shape
    z_color[:] = np.inf
    up, down = np.zeros(w + 2, np.float32), np.zeros(w + 2, np.float32)  # rows e - 1 and e, metres
    _load_row(depth, y0 - 1, units, up)
    _load_row(depth, y0, units, down)
    ve, he, vc = np.empty((3, w + 1), np.float32), np.empty((3, w), np.float32), np.empty((3, w), np.float32)
    j_lo, j_hi = np.empty(w + 1, np.int32), np.empty(w + 1, np.int32)
    i_top, i_end, i_next = np.empty(w, np.int32), np.empty(w, np.int32), np.empty(w, np.int32)
    for e in range(y0, y1 + 1):  # horizontal edge e: between depth rows e - 1 (up) and e (down)
        _rays_row(x_centres, y_edges[e], R, g_horizontal, e, he)
        for x in range(w):
            z_up, z_down, pad = _edge_depths(up[x + 1], down[x + 1], thr)
            i_end[x] = _first(
                _to_pixel(z_up, he[0, x], he[1, x], he[2, x], t, cam, k)[1] + slack[1] + pad, h_c
            )
            i_next[x] = _first(
                _to_pixel(z_down, he[0, x], he[1, x], he[2, x], t, cam, k)[1] - slack[1] - pad, h_c
            )
        if e > y0:  # row e - 1 is bounded above and below: scatter it
            _rays_row(x_centres, y_centres[e - 1], R, g_centre, e - 1, vc)
            for x in range(w):
                c = up[x + 1] * vc[2, x] + t[2]
                if up[x + 1] == 0 or c <= 0:
                    continue
                j0, nj = j_lo[x], j_hi[x + 1] - j_lo[x]
                j1 = min(j0 + 1, w_c - 1)
                for i in range(i_top[x], i_end[x]):
                    if 1 <= nj <= 2:  # the usual box width, without a data-dependent branch
                        old = z_color[i, j0]
                        z_color[i, j0] = c if c < old else old
                        old = z_color[i, j1]
                        z_color[i, j1] = c if (nj == 2) & (c < old) else old
                    else:
                        for j in range(j0, j0 + nj):
                            z_color[i, j] = min(c, z_color[i, j])
        if e == y1:
            break
        i_top[:] = i_next
        _rays_row(x_edges, y_centres[e], R, g_vertical, e, ve)
        for x in range(w + 1):  # vertical edges of row e: x - 1 | x
            z_left, z_right, pad = _edge_depths(down[x], down[x + 1], thr)
            j_hi[x] = _first(
                _to_pixel(z_left, ve[0, x], ve[1, x], ve[2, x], t, cam, k)[0] + slack[0] + pad, w_c
            )
            j_lo[x] = _first(
                _to_pixel(z_right, ve[0, x], ve[1, x], ve[2, x], t, cam, k)[0] - slack[0] - pad, w_c
            )
        up, down = down, up
        _load_row(depth, e + 1, units, down)


def f32(a: npt.ArrayLike) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _edge_slack(
    depth: Intrinsics, R: np.ndarray, t: np.ndarray, cam: np.ndarray, k: np.ndarray | None
) -> np.ndarray:
    """(2,) colour pixels: half the largest slant of a depth pixel's vertical edge in u and of its
    horizontal edge in v, seen by the colour camera (zero unless it is rotated about its axis). Each
    box is widened by it so that the boxes of one surface leave no gap between them."""
    slack = np.zeros(2)
    grid = np.meshgrid(np.linspace(0, depth.width - 1, 9), np.linspace(0, depth.height - 1, 9))
    for x, y in np.stack(grid, -1).reshape(-1, 2):
        # top-left, top-right, bottom-right corners
        corners = depth.normalized(
            np.array([x - 0.5, x + 0.5, x + 0.5]), np.array([y - 0.5, y - 0.5, y + 0.5])
        )
        a = f32(corners @ R[:, :2].T + R[:, 2])
        for z in (0.2, 1.0, 10.0):
            (_, v0), (u1, v1), (u2, _) = (_to_pixel(np.float32(z), *a[i], t, cam, k) for i in range(3))  # type: ignore[call-arg]
            slack = np.maximum(slack, [abs(u2 - u1) / 2, abs(v1 - v0) / 2])
    return slack


@dataclass(frozen=True)
class _Geometry:
    depth: Intrinsics
    color: Intrinsics
    T_color_depth: tuple[float, ...]


class DepthRegistration:
    """Depth frames registered onto their colour frame's grid (what ``rs.align(rs.stream.color)``
    makes), with the rays of the depth pixels' edges cached per geometry (both streams' intrinsics,
    extrinsics).

    same_surface: neighbouring depth pixels whose depths differ by at most this fraction of their
    mean are one surface (their colour boxes share an edge); farther apart, each keeps its own.
    """

    def __init__(self, same_surface: float = 0.02) -> None:
        self.same_surface = same_surface
        self._geometry: _Geometry | None = None
        self._args: tuple[object, ...] = ()

    @staticmethod
    def supports(color: Intrinsics) -> bool:
        """Whether the colour camera's lens model is one this registration projects with."""
        return color.model in _MODELS or not any(color.coeffs)

    def _prepare(self, geometry: _Geometry) -> None:
        if geometry == self._geometry:
            return
        depth, color = geometry.depth, geometry.color
        if not self.supports(color):
            raise UnsupportedIntrinsics(color.model)
        T = np.array(geometry.T_color_depth).reshape(4, 4)
        R = T[:3, :3]
        cols, rows = np.arange(depth.width, dtype=np.float64), np.arange(depth.height, dtype=np.float64)
        col_edges, row_edges = (
            np.append(cols - 0.5, depth.width - 0.5),
            np.append(rows - 0.5, depth.height - 0.5),
        )

        def rays(u: np.ndarray, v: np.ndarray) -> np.ndarray:  # (3, len(v), len(u)) R @ (x_n, y_n, 1)
            xy = depth.normalized(*np.meshgrid(u, v))
            return f32(np.moveaxis(xy @ R[:, :2].T + R[:, 2], -1, 0))

        distorted = depth.model != "none" and any(depth.coeffs)
        # without depth lens distortion x_n depends on the column only and y_n on the row only
        axes = tuple(f32((c - p) / f) for c, p, f in ((col_edges, depth.ppx, depth.fx), (cols, depth.ppx, depth.fx),
                                                      (row_edges, depth.ppy, depth.fy), (rows, depth.ppy, depth.fy)))  # fmt: skip
        grids = (
            (rays(col_edges, rows), rays(cols, row_edges), rays(cols, rows))
            if distorted
            else (None, None, None)
        )
        k = None
        if any(color.coeffs):
            k = f32([_MODELS[color.model], *color.coeffs])
        cam = f32([color.fx, color.fy, color.ppx, color.ppy])
        t = f32(T[:3, 3])
        slack = f32(_edge_slack(depth, R, t, cam, k) * 1.1)
        self._args = (axes, f32(R), grids, t, cam, k, np.float32(self.same_surface / 2), slack)
        self._geometry = geometry

    def register_arrays(self, depth_units: np.ndarray, units_m: float, depth: Intrinsics, color: Intrinsics,
                        T_color_depth: np.ndarray) -> np.ndarray:  # fmt: skip
        """(Hc, Wc) float32 z in the colour optical frame, metres, +inf where no depth lands.

        depth_units: (Hd, Wd) uint16 depth in ``units_m`` metres (0 = no depth), depth optical frame.
        T_color_depth: (4, 4) colour optical frame <- depth optical frame, metres.
        """
        if depth_units.shape != (depth.height, depth.width) or depth_units.dtype != np.uint16:
            raise ValueError(f"depth must be uint16 {(depth.height, depth.width)}, got {depth_units.dtype} "
                             f"{depth_units.shape}")  # fmt: skip
        self._prepare(_Geometry(depth, color, tuple(float(v) for v in np.asarray(T_color_depth).ravel())))
        z_color = np.empty((color.height, color.width), np.float32)
        _register_rows(  # type: ignore[call-arg]
            np.ascontiguousarray(depth_units), np.float32(units_m), 0, depth.height, *self._args, z_color
        )
        return z_color

    def register(self, depth: rs.depth_frame, color: rs.video_frame) -> tuple[np.ndarray, Intrinsics]:
        """The colour-grid z image (see :meth:`register_arrays`) of a librealsense depth + colour pair,
        and the colour intrinsics (the grid's)."""
        d_profile = depth.get_profile().as_video_stream_profile()
        c_profile = color.get_profile().as_video_stream_profile()
        d_intr = Intrinsics.from_rs(d_profile.get_intrinsics())
        c_intr = Intrinsics.from_rs(c_profile.get_intrinsics())
        T = extrinsics_matrix(d_profile.get_extrinsics_to(c_profile))
        z_color = self.register_arrays(
            np.asanyarray(depth.get_data()), depth.as_depth_frame().get_units(), d_intr, c_intr, T
        )
        return z_color, c_intr
