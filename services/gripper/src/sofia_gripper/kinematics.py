"""Motor angle <-> slider travel (slider-crank) <-> finger opening (calibration table).

The MX-64 turns a crank of radius ``r``; a rod of length ``l`` pushes a slider along an axis
offset by ``e`` from the crank centre; the slider bends the Fin-Ray fingers. With the crank angle
``theta`` measured from the slider axis (0 = crank pointing at the slider), the slider position is

    x(theta) = r cos(theta) + sqrt(l^2 - (r sin(theta) - e)^2)

and the slider travel is ``s = x(0) - x(theta)`` (0 at the crank's dead centre, growing as the
gripper closes). The map is monotonic between the two dead centres, where crank and rod are
collinear: ``theta`` in (asin(e / (l + r)), pi + asin(e / (l - r))) (:attr:`SliderCrank.theta_range`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .control_table import TICKS_PER_REV

FloatArray = npt.NDArray[np.float64]


class SliderCrank:
    """Slider-crank geometry: ``crank_radius_mm`` r, ``rod_length_mm`` l, ``offset_mm`` e."""

    def __init__(self, crank_radius_mm: float, rod_length_mm: float, offset_mm: float) -> None:
        if not (crank_radius_mm > 0 and rod_length_mm > crank_radius_mm + abs(offset_mm)):
            raise ValueError(
                f"slider-crank needs r > 0 and l > r + |e|, got r={crank_radius_mm} "
                f"l={rod_length_mm} e={offset_mm} (mm)"
            )
        self.r, self.l, self.e = float(crank_radius_mm), float(rod_length_mm), float(offset_mm)
        self.x0 = self.r + math.sqrt(self.l**2 - self.e**2)
        self.theta_range = (
            math.asin(self.e / (self.l + self.r)),
            math.pi + math.asin(self.e / (self.l - self.r)),
        )

    def travel(self, theta: Any) -> FloatArray:
        """Slider travel s (mm) for crank angles ``theta``: (n,) or scalar, radians."""
        theta = np.asarray(theta, dtype=np.float64)
        x = self.r * np.cos(theta) + np.sqrt(self.l**2 - (self.r * np.sin(theta) - self.e) ** 2)
        return np.asarray(self.x0 - x)

    def angle(self, travel_mm: Any) -> FloatArray:
        """Crank angle theta (rad, within ``theta_range``) for slider travels ``travel_mm``: (n,) or scalar, mm.

        Solves x cos(theta) + e sin(theta) = (x^2 + r^2 - l^2 + e^2) / (2 r) with x = x(0) - s.
        """
        x = self.x0 - np.asarray(travel_mm, dtype=np.float64)
        k = (x**2 + self.r**2 - self.l**2 + self.e**2) / (2 * self.r)
        radius = np.hypot(x, self.e)
        return np.asarray(np.arctan2(self.e, x) + np.arccos(np.clip(k / radius, -1.0, 1.0)))


class OpeningTable:
    """Measured finger opening (mm) at slider travels (mm); linear interpolation between rows.

    ``rows``: (n, 2) [travel_mm, opening_mm], travel strictly increasing, opening strictly
    decreasing (the fingers close as the slider advances).
    """

    def __init__(self, rows: Any) -> None:
        table = np.asarray(rows, dtype=np.float64)
        if table.ndim != 2 or table.shape[1] != 2 or table.shape[0] < 2 or not np.isfinite(table).all():
            raise ValueError(
                f"calibration table must be (n>=2, 2) finite [travel_mm, opening_mm], got {rows!r}"
            )
        if not (np.all(np.diff(table[:, 0]) > 0) and np.all(np.diff(table[:, 1]) < 0)):
            raise ValueError(
                f"calibration table needs increasing travel and decreasing opening, got {table.tolist()}"
            )
        self.travel_mm, self.opening_mm = table[:, 0], table[:, 1]

    def opening(self, travel_mm: Any) -> FloatArray:
        """Finger opening (mm) for slider travels (mm), clamped to the table's range."""
        return np.asarray(np.interp(travel_mm, self.travel_mm, self.opening_mm))

    def travel(self, opening_mm: Any) -> FloatArray:
        """Slider travel (mm) for finger openings (mm), clamped to the table's range."""
        return np.asarray(np.interp(opening_mm, self.opening_mm[::-1], self.travel_mm[::-1]))


class GripperKinematics:
    """Motor position (ticks) <-> crank angle (rad) <-> slider travel (mm) <-> opening (mm).

    ``zero_ticks``: the motor position at crank angle 0; closing increases the position.
    """

    def __init__(self, crank: SliderCrank, table: OpeningTable, zero_ticks: int) -> None:
        self.crank, self.table, self.zero_ticks = crank, table, zero_ticks

    def ticks_to_rad(self, ticks: Any) -> FloatArray:
        return np.asarray(
            (np.asarray(ticks, dtype=np.float64) - self.zero_ticks) * (2 * math.pi / TICKS_PER_REV)
        )

    def rad_to_ticks(self, theta: Any) -> FloatArray:
        return np.asarray(
            np.asarray(theta, dtype=np.float64) * (TICKS_PER_REV / (2 * math.pi)) + self.zero_ticks
        )

    def opening(self, ticks: Any) -> FloatArray:
        """Finger opening (mm) at motor positions ``ticks``."""
        return self.table.opening(self.crank.travel(self.ticks_to_rad(ticks)))

    def ticks(self, opening_mm: Any) -> FloatArray:
        """Motor positions (ticks, float) giving finger openings ``opening_mm``."""
        return self.rad_to_ticks(self.crank.angle(self.table.travel(opening_mm)))
