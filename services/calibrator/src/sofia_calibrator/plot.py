"""The lab's dissipation plot, done well: the blob mapped into the base frame before (the user's
guess, or the identity as in the lab's launch file) and after calibration, per axis and sample,
outliers marked, the lab's band (10 mm wide, drawn as +-5 mm about the middle of the inliers'
range: a spread within it passes); and the depth residual against depth, where a depth-scale error
shows as a slope."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sofia_schemas.transforms import rotation_angle

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
    from matplotlib.ticker import MaxNLocator

    fig = plt.figure(figsize=(13, 11), layout="constrained")
    fig.suptitle(
        f"{title}: per-axis spread {np.round(cal.spread_mm, 1).tolist()} mm over inliers "
        f"({'PASS' if cal.passes else 'FAIL'}, limit {LAB_SPREAD_LIMIT_MM:.0f} mm)"
    )
    before = "before (guess)" if cal.guess_given else "before (identity)"
    band = f"lab band, {LAB_SPREAD_LIMIT_MM:.0f} mm wide (+-{LAB_SPREAD_LIMIT_MM / 2:.0f} mm)"
    for row, (name, pts) in enumerate(((before, before_mm), ("calibrated (after)", after_mm))):
        for axis in range(3):
            a = fig.add_subplot(3, 3, 1 + axis + 3 * row)
            centre = 0.5 * (pts[inl, axis].max() + pts[inl, axis].min()) if inl.size else 0.0
            a.axhspan(centre - LAB_SPREAD_LIMIT_MM / 2, centre + LAB_SPREAD_LIMIT_MM / 2, color="tab:green",
                      alpha=0.15, label=band)  # fmt: skip
            a.plot(inl, pts[inl, axis], "o", c="tab:blue", label="inliers")
            if out.size:
                a.plot(out, pts[out, axis], "x", c="tab:red", ms=9, label="outliers")
            a.set_title(f"{'xyz'[axis]} of the mapped blob, {name}", fontsize=10)
            a.set_xlabel("sample")
            a.set_ylabel("mm from the blob's estimate" if axis == 0 else "mm")
            a.xaxis.set_major_locator(MaxNLocator(integer=True))
            if axis == 0:
                a.legend(fontsize=8)
    _depth_residuals(fig.add_subplot(3, 3, (7, 8)), cal, inl, out)
    note = fig.add_subplot(3, 3, 9)
    note.axis("off")
    t, ang = 1e3 * cal.T_flange_cam[:3, 3], np.degrees(rotation_angle(cal.T_flange_cam[:3, :3]))
    note.text(0.0, 1.0, f"samples: {len(cal.inliers)} inliers, {len(cal.outliers)} outliers {cal.outliers or ''}\n"
              f"camera correction: {cal.correction.model}, depth scale {cal.correction.depth_scale:.4f}\n"
              f"T_flange_cam: t = {np.round(t, 1).tolist()} mm,\n  rotation {ang:.1f} deg\n"
              f"spread over inliers: {np.round(cal.spread_mm, 1).tolist()} mm (limit {LAB_SPREAD_LIMIT_MM:.0f})",
              va="top", fontsize=9, family="monospace", wrap=True)  # fmt: skip
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _depth_residuals(ax, cal: Calibration, inl: np.ndarray, out: np.ndarray) -> None:  # type: ignore[no-untyped-def]
    """Camera-z residual (measured minus predicted blob, camera frame) against depth, for the rigid
    fit and the chosen model: a depth-scale error is a slope of the first."""
    R_base_cam = np.einsum("nij,jk->nik", cal.T_base_flange[:, :3, :3], cal.T_flange_cam[:3, :3])
    z = cal.p_cam[:, 2]
    dz = 1e3 * np.einsum("nji,nj->ni", R_base_cam, cal.mapped_base - cal.p_base)[:, 2]
    if cal.correction.model != "rigid":  # else it is the same fit as below
        ax.plot(z, cal.reference_residuals_mm[:, 2], "s", label="rigid fit (no correction)", alpha=0.8)
    ax.plot(z[inl], dz[inl], "o", label=f"{cal.correction.model} fit (the result)", alpha=0.8)
    if out.size:
        ax.plot(z[out], dz[out], "x", c="tab:red", ms=9, label="outliers")
    ax.axhline(0.0, c="grey", lw=0.8)
    ax.set_xlabel("measured depth z, m")
    ax.set_ylabel("depth residual, mm")
    ax.set_title(
        f"residual vs depth ({cal.correction.model}, scale {cal.correction.depth_scale:.4f})", fontsize=9
    )
    ax.legend(fontsize=7)
