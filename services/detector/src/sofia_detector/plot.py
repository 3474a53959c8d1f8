"""The board seen from above (base frame x/y, metres): fields, the points' mean height per 3 mm cell,
each object's footprint, centre, centroid and grasp, and the direction of the robot base."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import binned_statistic_2d
from sofia_schemas import Board
from sofia_schemas.messages import Detection

from .geometry.points import coords
from .pick import PickParams, pick_target, pickable

CELL_M = 0.003  # side of the height map's cells
ALLOWED, NOT_ALLOWED = "#2ca02c", "#ff7f0e"  # footprint colours
FINGERS, RED_FIELD = "#1f77b4", "#d62728"
STATUS_TEXT = {"ok": "{n} object(s) on the board", "no_object": "board seen, no object on it",
               "no_board": "no board found"}  # fmt: skip


def _rectangle(
    center: np.ndarray | tuple[float, ...], size: tuple[float, ...], yaw: float, **style: Any
) -> Any:
    """A matplotlib rectangle centred at ``center`` (2,), metres, turned by ``yaw`` (radians)."""
    from matplotlib.patches import Rectangle

    corner = np.asarray(center) - np.asarray(size) / 2
    return Rectangle(tuple(corner), *size, angle=np.degrees(yaw), rotation_point="center", **style)


def _label_rows_and_columns(ax: Any, board: Board, center: np.ndarray, R: np.ndarray) -> None:
    """Row numbers beyond the board's -y edge, column numbers beyond its -x edge: clear of objects."""
    fx, fy = board.field_size
    centers = board.field_centers_board()
    style = {"color": "0.2", "fontsize": 7, "ha": "center", "va": "center", "zorder": 2.6}
    for r in range(board.rows):
        ax.text(*(center + R @ (centers[r, 0] - [0.0, 0.8 * fy])), f"row {r}", **style)
    for col in range(board.cols):
        ax.text(*(center + R @ (centers[0, col] - [0.8 * fx, 0.0])), f"col {col}", **style)


def _draw_fingers(ax: Any, detection: Detection) -> None:
    """The fingertips and closing axis of the grasp of each object that may be picked."""
    for obj in pickable(detection, PickParams()):
        target = pick_target(obj, 0)
        y_axis = np.array([np.sin(target.yaw), -np.cos(target.yaw)])  # the flange y axis, base frame
        tips = np.array(obj.center[:2]) + np.outer([-1.0, 1.0], y_axis) * target.opening_mm / 2e3
        ax.plot(tips[:, 0], tips[:, 1], color=FINGERS, lw=1.2, ls="--", zorder=4.5)
        ax.plot(tips[:, 0], tips[:, 1], "s", color=FINGERS, ms=5, zorder=4.5)


def _mark_robot_base(ax: Any, center: np.ndarray, R: np.ndarray, extent: tuple[float, float]) -> None:
    """An arrow just outside the board's edge pointing towards the robot base (the base frame's origin)."""
    towards = -center / max(float(np.linalg.norm(center)), 1e-9)
    in_board = np.abs(R.T @ towards)  # the direction in the board's frame
    to_edge = min(e / 2 / max(d, 1e-9) for e, d in zip(extent, in_board, strict=True))
    tail = center + towards * (to_edge + 0.012)
    head = tail + towards * 0.05
    ax.annotate("", xy=head, xytext=tail, zorder=5, arrowprops={"arrowstyle": "->", "color": "0.2"})
    ax.text(head[0], head[1] - 0.012, "robot base", fontsize=7, color="0.2", ha="center", va="top", zorder=5)


def _height_map(xyz: np.ndarray, surface: float, limits: tuple[float, float, float, float]) -> np.ndarray:
    """(rows, cols) mean height above ``surface`` of the points (3, N) per ``CELL_M`` cell over
    ``limits`` (x0, x1, y0, y1); NaN where there is no point."""
    x0, x1, y0, y1 = limits
    bins = (max(1, round((y1 - y0) / CELL_M)), max(1, round((x1 - x0) / CELL_M)))
    return binned_statistic_2d(xyz[1], xyz[0], xyz[2] - surface, bins=bins, range=((y0, y1), (x0, x1)))[0]


def plot_detection(
    points: np.ndarray, board: Board, detection: Detection, out: str | Path, title: str = ""
) -> Path:
    """Write a PNG of ``detection`` over ``points`` ((N, 3) or (H, W, 3), base frame) to ``out``;
    ``title`` names the cloud, the plot adds what was found."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_rgba
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
    for (r, col), _ in np.ndenumerate(centers[..., 0]):  # red fields tinted, each field outlined
        fill = to_rgba(RED_FIELD if board.is_allowed(r, col) else "white", 0.35)
        ax.add_patch(
            _rectangle(center + R @ centers[r, col], (fx, fy), yaw, fc=fill, ec="0.3", lw=0.6, zorder=2.5)
        )
    _label_rows_and_columns(ax, board, center, R)
    ex, ey = board.extent
    margin = 0.08
    (x0, x1), (y0, y1) = (
        (center[0] - ex / 2 - margin, center[0] + ex / 2 + margin),
        (center[1] - ey / 2 - margin, center[1] + ey / 2 + margin),
    )
    if xyz.shape[1]:
        im = ax.imshow(_height_map(xyz, surface, (x0, x1, y0, y1)), extent=(x0, x1, y0, y1), origin="lower",
                       cmap="Greys", vmin=-0.02, vmax=0.12, zorder=2, interpolation="nearest")  # fmt: skip
        fig.colorbar(im, ax=ax, label="points seen: height above the board (m), beside the board too",
                     orientation="horizontal", shrink=0.6, pad=0.08)  # fmt: skip
    lines = []
    for i, obj in enumerate(detection.objects, 1):
        ax.add_patch(_rectangle(obj.center[:2], obj.extents[:2], obj.yaw, fill=False, lw=1.5, zorder=3,
                                ec=ALLOWED if obj.allowed else NOT_ALLOWED))  # fmt: skip
        ax.plot(*obj.center[:2], "x", color="k", ms=9, mew=2, zorder=4)
        ax.plot(*obj.centroid[:2], "o", mfc="none", mec="m", ms=8, zorder=4)
        ax.annotate(str(i), obj.center[:2], xytext=(7, 7), textcoords="offset points", fontsize=8, zorder=5,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8})  # fmt: skip
        where = "red field, to pick" if obj.allowed else "not a red field, not to pick"
        field = f"row {obj.field[0]}, col {obj.field[1]}" if obj.field is not None else "off the board's grid"
        lines.append(f"{i}: {field} ({where}), confidence {obj.confidence:.2f},\n"
                     f"    centre ({obj.center[0]:.3f}, {obj.center[1]:.3f}, {obj.center[2]:.3f}) m")  # fmt: skip
    _draw_fingers(ax, detection)
    _mark_robot_base(ax, center, R, board.extent)
    ax.legend(handles=[
        Patch(fc=RED_FIELD, alpha=0.35, label="red field: its objects are picked"),
        Line2D([], [], color=ALLOWED, lw=1.5, label="object on a red field"),
        Line2D([], [], color=NOT_ALLOWED, lw=1.5, label="object on another field (not picked)"),
        Line2D([], [], color=FINGERS, marker="s", ms=5, ls="--", label="fingertips of the grasp"),
        Line2D([], [], marker="x", color="k", ls="none", ms=8, mew=2, label="centre"),
        Line2D([], [], marker="o", mfc="none", mec="m", ls="none", ms=7, label="centroid"),
        *(Line2D([], [], ls="none", label=line) for line in lines),
    ], loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False)  # fmt: skip
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel(f"x ({board.frame_id}, m)")
    ax.set_ylabel(f"y ({board.frame_id}, m)")
    status = STATUS_TEXT.get(detection.status, detection.status).format(n=len(detection.objects))
    ax.set_title(f"{title}: {status}" if title else status)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return out
