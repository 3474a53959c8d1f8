"""Tuning of the detector (metres, radians). The defaults suit a D435 0.5-1 m above the board."""

from __future__ import annotations

from dataclasses import dataclass

DEFAULT_PALETTE: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("red", (200, 30, 35)),
    ("orange", (235, 120, 30)),
    ("yellow", (230, 200, 40)),
    ("green", (40, 160, 60)),
    ("blue", (30, 80, 200)),
    ("purple", (130, 50, 160)),
    ("white", (235, 235, 230)),
    ("grey", (128, 128, 128)),
    ("black", (25, 25, 28)),
)


@dataclass(frozen=True)
class DetectorParams:
    """Thresholds of :func:`sofia_detector.detect` (metres and radians unless named otherwise)."""

    stride: int = 4  # pixel step of the coarse grid of organized clouds (plane fit, outline, object seeds)
    board_band: float = 0.05  # points this near the configured board plane are board candidates
    board_shrink: float = 0.02  # the plane is fitted only inside the configured board shrunk by this
    plane_thresholds: tuple[float, ...] = (0.025, 0.01, 0.006)  # inlier distances of the successive refits
    outline_band: float = 0.008  # |height| below which a point belongs to the board top (outline)
    outline_margin: float = 0.08  # the outline is searched within the configured board grown by this
    max_board_yaw: float = 0.105  # 6 degrees: largest in-plane turn of the real board from the configured
    max_rim: float = 0.05  # widest border of the board around its fields (outline sanity check)
    # floor of the height above the measured plane that marks a coarse object pixel (raised to noise_k
    # standard deviations of the board's fitted depth noise)
    seed_height: float = 0.005
    object_height: float = 0.003  # floor of the height of an object's points (raised to point_k sigmas)
    max_height: float = 0.30  # points higher than this (the gripper fingers, the arm) are ignored
    field_margin: float = 0.02  # an object's centre must lie within the field grid grown by this margin
    min_seed_pixels: int = 3  # smallest coarse component that is examined
    min_points: int = 30  # smallest object (full-resolution points)
    min_object_height: float = 0.005  # an object must rise this far above the board (the height floor)
    curvature: float = 3.0  # |d| (1/m) of the top fit h = a + b x + c y + d r^2 beyond which it is curved
    cell: float = 0.004  # occupancy-grid cell of unorganized clouds
    noise_k: float = 4.0  # seed_height, object_height: floors in units of the board's fitted depth noise
    point_k: float = 3.0
    # flying pixels: a point needs two of its 8 neighbours within this many pixel spacings (plus the
    # depth noise) in 3D
    neighbour_px: float = 4.0
    colour_tol: float = 0.25  # colour distance (depth.clean.chroma) of holes bridged into an object
    min_width: float = 0.008  # narrowest footprint of an object (thinner: a sheet of flying pixels)
    palette: tuple[tuple[str, tuple[int, int, int]], ...] = DEFAULT_PALETTE  # (name, sRGB) of the colours
