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
    """Thresholds of :func:`sofia_detector.detect`.

    stride: pixel step of the coarse grid of organized clouds (plane fit, outline, object seeds).
    board_band: points within this distance of the configured board plane are board candidates.
    board_shrink: the plane is fitted only inside the configured board shrunk by this margin.
    plane_thresholds: inlier distances of the successive robust plane refits.
    outline_band: |height| below which a point belongs to the board top (outline).
    outline_margin: the outline is searched within the configured board grown by this margin.
    max_board_yaw: largest in-plane rotation of the real board from the configured one.
    max_rim: widest border of the board around its fields (outline sanity check).
    seed_height: floor of the height above the measured plane that marks a coarse object pixel
        (the board's fitted noise raises it to ``noise_k`` standard deviations).
    object_height: floor of the height of the points that form an object (full resolution;
        raised to ``point_k`` noise standard deviations).
    noise_k, point_k: the two thresholds in units of the board's fitted depth noise.
    max_height: points higher than this (the gripper fingers, the arm) are ignored.
    field_margin: an object's centre must lie within the field grid grown by this margin.
    min_seed_pixels: smallest coarse component that is examined.
    min_points: smallest object (full-resolution points).
    min_object_height: an object must rise this far above the board (the height floor).
    neighbour_px: flying pixels: a point needs two of its 8 neighbours within this many pixel
        spacings (plus the depth noise) in 3D.
    min_width: narrowest footprint of an object (thinner: a sheet of flying pixels).
    colour_tol: colour distance (see :func:`.depth_clean.chroma`) of holes bridged into an object.
    palette: (name, sRGB) of the colours objects are named after.
    curvature: |d| (1/m) of the top fit ``h = a + b x + c y + d r^2`` above which a top is curved.
    cell: occupancy-grid cell of unorganized clouds.
    """

    stride: int = 4
    board_band: float = 0.05
    board_shrink: float = 0.02
    plane_thresholds: tuple[float, ...] = (0.025, 0.01, 0.006)
    outline_band: float = 0.008
    outline_margin: float = 0.08
    max_board_yaw: float = 0.105  # 6 degrees
    max_rim: float = 0.05
    seed_height: float = 0.005
    object_height: float = 0.003
    max_height: float = 0.30
    field_margin: float = 0.02
    min_seed_pixels: int = 3
    min_points: int = 30
    min_object_height: float = 0.005
    curvature: float = 3.0
    cell: float = 0.004
    noise_k: float = 4.0
    point_k: float = 3.0
    neighbour_px: float = 4.0
    colour_tol: float = 0.25
    min_width: float = 0.008
    palette: tuple[tuple[str, tuple[int, int, int]], ...] = DEFAULT_PALETTE
