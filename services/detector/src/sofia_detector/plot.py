"""The board seen from above: fields (red ones marked), the points, each object's footprint,
centre and centroid. Base frame x/y, metres."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from sofia_schemas import Board
from sofia_schemas.messages import Detection

from .plane import coords

MAX_PLOT_POINTS = 60_000


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
    ax.text(*fc, f"{rc[0]},{rc[1]}", color="0.2", fontsize=8, ha="center", va="center", zorder=2.6)


def plot_detection(
    points: np.ndarray, board: Board, detection: Detection, out: str | Path, title: str = ""
) -> Path:
    """Write a PNG of ``detection`` over ``points`` ((N, 3) or (H, W, 3), base frame) to ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xyz = coords(points).reshape(3, -1)
    finite = np.flatnonzero(np.isfinite(xyz).all(axis=0))
    finite = finite[:: max(1, finite.size // MAX_PLOT_POINTS)]
    xyz = xyz[:, finite]
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
    if xyz.shape[1]:
        sc = ax.scatter(
            xyz[0], xyz[1], c=np.clip(xyz[2] - surface, -0.02, 0.12), s=0.2, cmap="viridis", zorder=2
        )
        fig.colorbar(sc, ax=ax, label="height above the board (m)", shrink=0.7)
    for i, obj in enumerate(detection.objects):
        colour = "#2ca02c" if obj.allowed else "#ff7f0e"
        corners = _corners(np.array(obj.center[:2]), (obj.extents[0], obj.extents[1]), obj.yaw)
        ax.plot(corners[:, 0], corners[:, 1], color=colour, lw=1.5, zorder=3)
        ax.plot(*obj.center[:2], "x", color="k", ms=9, mew=2, zorder=4, label="centre" if i == 0 else None)
        ax.plot(
            *obj.centroid[:2], "o", mfc="none", mec="m", ms=8, zorder=4, label="centroid" if i == 0 else None
        )
        ax.annotate(
            f"{'allowed' if obj.allowed else 'NOT allowed'} field {obj.field}\n"
            f"centre ({obj.center[0]:.3f}, {obj.center[1]:.3f}, {obj.center[2]:.3f})",
            obj.center[:2], xytext=(8, 8), textcoords="offset points", fontsize=7, zorder=5,
        )  # fmt: skip
    ex, ey = board.extent
    margin = 0.08
    ax.set_xlim(center[0] - ex / 2 - margin, center[0] + ex / 2 + margin)
    ax.set_ylim(center[1] - ey / 2 - margin, center[1] + ey / 2 + margin)
    ax.set_aspect("equal")
    ax.set_xlabel(f"x ({board.frame_id}, m)")
    ax.set_ylabel(f"y ({board.frame_id}, m)")
    ax.set_title(title or f"{detection.status}: {len(detection.objects)} object(s)")
    if detection.objects:
        ax.legend(loc="upper right", fontsize=8)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return out
