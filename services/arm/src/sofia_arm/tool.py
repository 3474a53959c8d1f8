"""The tool on the flange and the surface under the arm: where the tool's lowest point is for
flange poses, and the flange poses a motion passes through.

Frames: base = ``panda_link0`` (z up), flange = ``panda_link8`` (its z axis points out of the
flange, towards the fingertips). Metres, radians.

SofIA's tool is a box from the flange down to the fingertips, ``fingertip_offset_m`` along the
flange z axis and ``finger_half_width_m`` either side along the flange x and y axes (the fingers
open up to about 10 cm): its eight corners stand for it. A bare flange is the flange origin.
The surface is the table/board top, a horizontal plane at ``surface_z`` (base frame), which
no point of the tool may come closer to than ``margin_m``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp
from sofia_schemas.kinematics import panda_fk

PATH_SAMPLES = 24  # poses checked along a motion's path (ends included)


@dataclass(frozen=True)
class Tool:
    """The tool's outline as points in the flange frame (k, 3), metres."""

    name: str
    points_flange: np.ndarray
    fingertip_offset_m: float

    @classmethod
    def fingers(cls, fingertip_offset_m: float, finger_half_width_m: float) -> Tool:
        """The box of two fingers: flange down to the fingertips, ``finger_half_width_m`` wide each side."""
        h, d = finger_half_width_m, fingertip_offset_m
        corners = np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (0.0, d)])
        return cls("sofia", corners, d)

    @classmethod
    def bare_flange(cls) -> Tool:
        return cls("flange", np.zeros((1, 3)), 0.0)

    def lowest(self, T_base_flange: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For flange poses (n, 4, 4) (base frame): the tool's lowest point of each (n, 3), base
        frame, and its height (n,) m."""
        T = np.asarray(T_base_flange, dtype=np.float64).reshape(-1, 4, 4)
        points_base = np.einsum("nij,kj->nki", T[:, :3, :3], self.points_flange) + T[:, None, :3, 3]
        k = np.argmin(points_base[:, :, 2], axis=1)
        low = points_base[np.arange(len(T)), k]
        return low, low[:, 2]


@dataclass(frozen=True)
class Surface:
    """The table/board top: a horizontal plane at ``z`` (base frame, m), kept ``margin_m`` clear of."""

    z: float
    margin_m: float
    source: str  # where the height comes from: "board file PATH" or "configured plane"

    @property
    def lowest_allowed(self) -> float:
        return self.z + self.margin_m


def line_path(T_from: np.ndarray, T_to: np.ndarray, n: int = PATH_SAMPLES) -> np.ndarray:
    """(n, 4, 4) flange poses along a straight Cartesian line from ``T_from`` to ``T_to`` (4, 4):
    positions linear, orientations by spherical interpolation."""
    s = np.linspace(0.0, 1.0, n)
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([T_from[:3, :3], T_to[:3, :3]])))
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = slerp(s).as_matrix()
    T[:, :3, 3] = (1.0 - s)[:, None] * T_from[:3, 3] + s[:, None] * T_to[:3, 3]
    return T


def joint_path(q_from: np.ndarray, q_to: np.ndarray, n: int = PATH_SAMPLES) -> np.ndarray:
    """(n, 4, 4) flange poses along a joint motion from ``q_from`` to ``q_to`` (7,) rad (a
    synchronised joint motion moves all joints along the straight line in joint space)."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    return np.asarray(panda_fk((1.0 - s) * q_from + s * q_to, check_limits=False))
