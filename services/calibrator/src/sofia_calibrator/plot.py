"""The lab's dissipation plot, done well: the blob mapped into the base frame before (start: guess
or linear closed form) and after calibration, in 3D and per axis, outliers marked, the 1 cm band."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .calibrate import Calibration
from .diagnostics import LAB_SPREAD_LIMIT_MM


def plot_calibration(cal: Calibration, path: str | Path, title: str = "Hand-eye calibration") -> Path:
    """Write a PNG of the calibration to ``path`` (matplotlib, Agg backend); returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    inl, out = np.array(cal.inliers, dtype=int), np.array(cal.outliers, dtype=int)
    before_mm = 1e3 * (cal.mapped_start - cal.p_base)
    after_mm = 1e3 * (cal.mapped_base - cal.p_base)
    fig = plt.figure(figsize=(13, 7.5))
    fig.suptitle(
        f"{title}: per-axis spread {np.round(cal.spread_mm, 1).tolist()} mm over inliers "
        f"({'PASS' if cal.passes else 'FAIL'}, limit {LAB_SPREAD_LIMIT_MM:.0f} mm)"
    )
    for col, (name, pts) in enumerate((("start (before)", before_mm), ("calibrated (after)", after_mm))):
        ax = fig.add_subplot(2, 4, 1 + 4 * col, projection="3d")
        ax.scatter(*pts[inl].T, c="tab:blue", label="inliers")
        if out.size:
            ax.scatter(*pts[out].T, c="tab:red", marker="x", s=60, label="outliers")
        ax.set_title(f"mapped blob, {name}")
        ax.set_xlabel("x mm")
        ax.set_ylabel("y mm")
        ax.set_zlabel("z mm")
        ax.legend(fontsize=7)
        for axis in range(3):
            a = fig.add_subplot(2, 4, 2 + axis + 4 * col)
            centre = 0.5 * (pts[inl, axis].max() + pts[inl, axis].min()) if inl.size else 0.0
            a.axhspan(centre - LAB_SPREAD_LIMIT_MM / 2, centre + LAB_SPREAD_LIMIT_MM / 2, color="tab:green",
                      alpha=0.15, label="1 cm band")  # fmt: skip
            a.plot(inl, pts[inl, axis], "o", c="tab:blue", label="inliers")
            if out.size:
                a.plot(out, pts[out, axis], "x", c="tab:red", ms=9, label="outliers")
            a.set_title(f"{'xyz'[axis]} of mapped blob, {name}", fontsize=9)
            a.set_xlabel("sample")
            a.set_ylabel("mm from target")
            if axis == 0:
                a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
