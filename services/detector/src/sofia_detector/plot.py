"""The board seen from above: fields (red ones marked), the points' height above the board (mean per
3 mm cell, so the PNG stays small), each object's footprint, centre and centroid, numbered on the
plot and described under it. Base frame x/y, metres."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from sofia_schemas import Board
from sofia_schemas.messages import Detection

from .geometry.points import coords

CELL_M = 0.003  # side of the height map's cells
ALLOWED, NOT_ALLOWED = "#2ca02c", "#ff7f0e"  # footprint colours


def _corners(center: np.ndarray, size: tuple[float, float], yaw: float) -> np.ndarray:
    """(5, 2) closed outline of a rectangle centred at ``center`` (2,) rotated by ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    half = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]]) * np.asarray(size) / 2
    return center + half @ np.array([[c, s], [-s, c]])


def _draw_field(
    ax: Any, fc: np.ndarray, size: tuple[float, float], yaw: float, rc: tuple[int, int], red: bool
) -> None:
    corners = _corners(fc, size, yaw)
    ax.fill(corners[:, 0], corners[:, 1], color="#d62728" if red else "white", alpha=0.35, zorder=2.5, lw=0)
    ax.plot(corners[:, 0], corners[:, 1], color="0.3", lw=0.6, zorder=2.6)
    corner = 0.85 * corners[3] + 0.15 * corners[1]  # inside the field's top-left corner, clear of objects
    ax.text(*corner, f"{rc[0]},{rc[1]}", color="0.2", fontsize=7, ha="center", va="center", zorder=2.6)


def _height_map(xyz: np.ndarray, surface: float, limits: tuple[float, float, float, float]) -> np.ndarray:
    """(rows, cols) mean height above ``surface`` of the points (3, N) per ``CELL_M`` cell over
    ``limits`` (x0, x1, y0, y1); NaN where there is no point."""
    x0, x1, y0, y1 = limits
    bins = (max(1, round((y1 - y0) / CELL_M)), max(1, round((x1 - x0) / CELL_M)))
    rng = ((y0, y1), (x0, x1))
    total, _, _ = np.histogram2d(xyz[1], xyz[0], bins=bins, range=rng, weights=xyz[2] - surface)
    count, _, _ = np.histogram2d(xyz[1], xyz[0], bins=bins, range=rng)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan)


def plot_detection(
    points: np.ndarray, board: Board, detection: Detection, out: str | Path, title: str = ""
) -> Path:
    """Write a PNG of ``detection`` over ``points`` ((N, 3) or (H, W, 3), base frame) to ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    xyz = coords(points).reshape(3, -1)
    xyz = xyz[:, np.isfinite(xyz).all(axis=0)]
    center = np.array(detection.board_center[:2] if detection.board_center else board.center)
    yaw = detection.board_yaw if detection.board_yaw is not None else board.yaw
    surface = detection.board_center[2] if detection.board_center else board.surface_z
    fig, ax = plt.subplots(figsize=(8, 7))
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s], [s, c]])
    fx, fy = board.field_size
    centers = board.field_centers_board()
    for r in range(board.rows):
        for col in range(board.cols):
            _draw_field(ax, center + R @ centers[r, col], (fx, fy), yaw, (r, col), board.is_allowed(r, col))
    ex, ey = board.extent
    margin = 0.08
    (x0, x1), (y0, y1) = (
        (center[0] - ex / 2 - margin, center[0] + ex / 2 + margin),
        (center[1] - ey / 2 - margin, center[1] + ey / 2 + margin),
    )
    if xyz.shape[1]:
        im = ax.imshow(_height_map(xyz, surface, (x0, x1, y0, y1)), extent=(x0, x1, y0, y1), origin="lower",
                       cmap="Greys", vmin=-0.02, vmax=0.12, zorder=2, interpolation="nearest")  # fmt: skip
        fig.colorbar(im, ax=ax, label="height above the board (m)", orientation="horizontal", shrink=0.6,
                     pad=0.08)  # fmt: skip
    lines = []
    for i, obj in enumerate(detection.objects, 1):
        corners = _corners(np.array(obj.center[:2]), (obj.extents[0], obj.extents[1]), obj.yaw)
        ax.plot(corners[:, 0], corners[:, 1], color=ALLOWED if obj.allowed else NOT_ALLOWED, lw=1.5, zorder=3)
        ax.plot(*obj.center[:2], "x", color="k", ms=9, mew=2, zorder=4)
        ax.plot(*obj.centroid[:2], "o", mfc="none", mec="m", ms=8, zorder=4)
        ax.annotate(str(i), obj.center[:2], xytext=(7, 7), textcoords="offset points", fontsize=8, zorder=5,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8})  # fmt: skip
        lines.append(f"{i}: {'allowed' if obj.allowed else 'NOT allowed'} field {obj.field}, centre "
                     f"({obj.center[0]:.3f}, {obj.center[1]:.3f}, {obj.center[2]:.3f}) m")  # fmt: skip
    ax.legend(handles=[
        Patch(fc="#d62728", alpha=0.35, label="allowed (red) field"),
        Line2D([], [], color=ALLOWED, lw=1.5, label="object on an allowed field"),
        Line2D([], [], color=NOT_ALLOWED, lw=1.5, label="object NOT on an allowed field"),
        Line2D([], [], marker="x", color="k", ls="none", ms=8, mew=2, label="centre"),
        Line2D([], [], marker="o", mfc="none", mec="m", ls="none", ms=7, label="centroid"),
        *(Line2D([], [], ls="none", label=line) for line in lines),
    ], loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False)  # fmt: skip
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel(f"x ({board.frame_id}, m)")
    ax.set_ylabel(f"y ({board.frame_id}, m)")
    ax.set_title(title or f"{detection.status}: {len(detection.objects)} object(s)")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return out
