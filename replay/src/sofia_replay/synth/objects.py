"""Objects of the lab beyond boxes, cylinders and balls: low pucks, bottles, cones, cylinders lying on
their side and L-shaped blocks, in the colours of a palette.

Every object's frame has its origin at the centre of its bounding box (the truth the detector's
``center`` is compared with), z up, x along its length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation
from sofia_schemas import Board

KINDS = ("box", "cylinder", "sphere", "puck", "bottle", "cone", "lying", "irregular")

# reference sRGB of the palette colours objects are painted in (the detector's default palette)
PAINT: dict[str, tuple[int, int, int]] = {
    "red": (200, 30, 35),
    "orange": (235, 120, 30),
    "yellow": (230, 200, 40),
    "green": (40, 160, 60),
    "blue": (30, 80, 200),
    "purple": (130, 50, 160),
    "white": (235, 235, 230),
    "grey": (128, 128, 128),
    "black": (25, 25, 28),
}


@dataclass
class RealObject:
    """Ground truth of one object (base frame, metres, radians).

    kind: one of :data:`KINDS`. T_base_obj: (4, 4) pose of the bounding-box centre. extents: (3,)
    length, width, height of the bounding box in the object's axes. colour: palette name; rgb: the
    paint (0-255). field: (row, col) of the field the object stands on.
    """

    kind: str
    T_base_obj: np.ndarray
    extents: np.ndarray
    colour: str
    rgb: tuple[int, int, int]
    field: tuple[int, int]
    allowed: bool

    @property
    def center(self) -> np.ndarray:
        """(3,) bounding-box centre, base frame."""
        return self.T_base_obj[:3, 3].copy()

    def to_json(self) -> dict[str, object]:
        return {
            "shape": self.kind,
            "center": self.center.tolist(),
            "extents": self.extents.tolist(),
            "field": list(self.field),
            "allowed": self.allowed,
            "colour": self.colour,
            "rgb": list(self.rgb),
            "T_base_obj": self.T_base_obj.tolist(),
        }


def _T(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _box(size: tuple[float, float, float], center: tuple[float, float, float]) -> o3d.geometry.TriangleMesh:
    m = o3d.geometry.TriangleMesh.create_box(*size)
    m.translate(np.asarray(center) - np.asarray(size) / 2)
    return m


def _cyl(r: float, h: float, z0: float) -> o3d.geometry.TriangleMesh:
    m = o3d.geometry.TriangleMesh.create_cylinder(r, h, resolution=96, split=1)
    m.translate((0.0, 0.0, z0 + h / 2))
    return m


def object_mesh_local(kind: str, ext: np.ndarray) -> o3d.geometry.TriangleMesh:
    """Mesh of an object of ``kind`` and bounding box ``ext`` (3,), in its own frame."""
    L, W, H = (float(v) for v in ext)
    if kind == "box" or (kind == "puck" and L != W):
        return _box((L, W, H), (0, 0, 0))
    if kind in ("cylinder", "puck"):
        return _cyl(L / 2, H, -H / 2)
    if kind == "sphere":
        return o3d.geometry.TriangleMesh.create_sphere(L / 2, resolution=48)
    if kind == "cone":
        m = o3d.geometry.TriangleMesh.create_cone(L / 2, H, resolution=96, split=1)
        m.translate((0.0, 0.0, -H / 2))
        return m
    if kind == "lying":  # a cylinder on its side, axis along x
        m = _cyl(W / 2, L, -L / 2)
        m.rotate(Rotation.from_euler("y", 90, degrees=True).as_matrix(), center=(0, 0, 0))
        return m
    if kind == "bottle":  # body, shoulder, neck
        r, rn = L / 2, min(0.013, L / 4)
        body, shoulder, neck = 0.68 * H, 0.17 * H, 0.15 * H
        cone = o3d.geometry.TriangleMesh.create_cone(r, shoulder * r / (r - rn), resolution=96, split=1)
        cone.translate((0.0, 0.0, -H / 2 + body))
        top = _cyl(rn, neck + 0.001, H / 2 - neck - 0.001)
        return _cyl(r, body, -H / 2) + cone + top
    if kind == "irregular":  # an L-shaped block of one height
        a = _box((L, W / 2, H), (0, -W / 4, 0))
        b = _box((L / 2, W / 2 + 0.002, H), (-L / 4, W / 4 - 0.001, 0))
        return a + b
    raise ValueError(f"object kind {kind!r} is not one of {KINDS}")


def random_extents(kind: str, rng: np.random.Generator) -> np.ndarray:
    """(3,) bounding box of a random object of ``kind``, metres."""
    if kind == "box":
        return rng.uniform(0.03, 0.09, 3)
    if kind == "cylinder":
        d, h = rng.uniform(0.03, 0.09, 2)
        return np.array([d, d, h])
    if kind == "sphere":
        return np.full(3, rng.uniform(0.035, 0.09))
    if kind == "puck":
        d = rng.uniform(0.04, 0.08)
        return np.array([d, d, rng.uniform(0.010, 0.014)])
    if kind == "bottle":
        d = rng.uniform(0.055, 0.085)
        return np.array([d, d, rng.uniform(0.15, 0.25)])
    if kind == "cone":
        d = rng.uniform(0.05, 0.09)
        return np.array([d, d, rng.uniform(0.04, 0.10)])
    if kind == "lying":
        d = rng.uniform(0.03, 0.06)
        return np.array([rng.uniform(0.07, 0.11), d, d])
    if kind == "irregular":
        return np.array([rng.uniform(0.05, 0.09), rng.uniform(0.04, 0.08), rng.uniform(0.02, 0.06)])
    raise ValueError(f"object kind {kind!r} is not one of {KINDS}")


def place_object(
    board: Board,
    T_base_board: np.ndarray,
    kind: str,
    fld: tuple[int, int],
    colour: str,
    rng: np.random.Generator,
    extents: np.ndarray | None = None,
) -> RealObject:
    """A random object of ``kind`` with random yaw inside field ``fld`` of the true board."""
    ext = random_extents(kind, rng) if extents is None else np.asarray(extents, dtype=float)
    r_fp = 0.5 * np.hypot(ext[0], ext[1])
    slack = np.maximum(np.array(board.field_size) / 2 - r_fp - 0.005, 0.0)
    xy = board.field_centers_board()[fld] + rng.uniform(-slack, slack)
    R = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi)).as_matrix()
    T_base_obj = T_base_board @ _T(R, np.array([xy[0], xy[1], ext[2] / 2]))
    paint = np.clip(np.array(PAINT[colour]) + rng.integers(-12, 13, 3), 0, 255)
    rgb = (int(paint[0]), int(paint[1]), int(paint[2]))
    return RealObject(kind, T_base_obj, ext, colour, rgb, fld, board.is_allowed(*fld))


def object_tmesh(obj: RealObject) -> o3d.t.geometry.TriangleMesh:
    """Ray-casting mesh of ``obj`` in the base frame."""
    m = object_mesh_local(obj.kind, obj.extents)
    m.transform(obj.T_base_obj)
    return o3d.t.geometry.TriangleMesh.from_legacy(m)
