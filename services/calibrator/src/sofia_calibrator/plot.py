"""The lab's dissipation plot, done well: the blob mapped into the base frame before (the user's
guess, or the identity as in the lab's launch file) and after calibration, in 3D and per axis,
outliers marked, the 1 cm band; and the depth residual against depth, where a depth-scale error
shows as a slope."""

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
    fig = plt.figure(figsize=(13, 10.5))
    fig.suptitle(
        f"{title}: per-axis spread {np.round(cal.spread_mm, 1).tolist()} mm over inliers "
        f"({'PASS' if cal.passes else 'FAIL'}, limit {LAB_SPREAD_LIMIT_MM:.0f} mm)"
    )
    before = "before (guess)" if cal.guess_given else "before (identity)"
    for col, (name, pts) in enumerate(((before, before_mm), ("calibrated (after)", after_mm))):
        ax = fig.add_subplot(3, 4, 1 + 4 * col, projection="3d")
        ax.scatter(*pts[inl].T, c="tab:blue", label="inliers")
        if out.size:
            ax.scatter(*pts[out].T, c="tab:red", marker="x", s=60, label="outliers")
        ax.set_title(f"mapped blob, {name}")
        ax.set_xlabel("x mm")
        ax.set_ylabel("y mm")
        ax.set_zlabel("z mm")
        ax.legend(fontsize=7)
        for axis in range(3):
            a = fig.add_subplot(3, 4, 2 + axis + 4 * col)
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
    _depth_residuals(fig.add_subplot(3, 2, 5), cal, inl, out)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _depth_residuals(ax, cal: Calibration, inl: np.ndarray, out: np.ndarray) -> None:  # type: ignore[no-untyped-def]
    """Camera-z residual (measured minus predicted blob, camera frame) against depth, for the rigid
    fit and the chosen model: a depth-scale error is a slope of the first."""
    R_base_cam = np.einsum("nij,jk->nik", cal.T_base_flange[:, :3, :3], cal.T_flange_cam[:3, :3])
    z = cal.p_cam[:, 2]
    dz = 1e3 * np.einsum("nji,nj->ni", R_base_cam, cal.mapped_base - cal.p_base)[:, 2]
    ax.plot(z, cal.reference_residuals_mm[:, 2], "s", label="rigid fit (no correction)", alpha=0.8)
    ax.plot(z[inl], dz[inl], "o", label=f"{cal.correction.model} fit", alpha=0.8)
    if out.size:
        ax.plot(z[out], dz[out], "x", c="tab:red", ms=9, label="outliers")
    ax.axhline(0.0, c="grey", lw=0.8)
    ax.set_xlabel("measured depth z, m")
    ax.set_ylabel("depth residual, mm")
    ax.set_title(
        f"residual vs depth ({cal.correction.model}, scale {cal.correction.depth_scale:.4f})", fontsize=9
    )
    ax.legend(fontsize=7)
