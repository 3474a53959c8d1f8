"""The lab's dissipation plot, done well: the blob mapped into the base frame before (the guess, or
the identity as in the lab's launch file) and after calibration, per axis and sample, then the result
alone, zoomed, with outliers and the lab's 10 mm band (+-5 mm about the middle of the inliers'
range); the depth residual against depth (a depth-scale error shows as a slope); and each flange
pose's rotation from their mean about the base axes (the observability advice is about these)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sofia_schemas.transforms import rotation_angle

from .fitting.calibrate import Calibration
from .fitting.diagnostics import LAB_SPREAD_LIMIT_MM


def plot_calibration(cal: Calibration, path: str | Path, title: str = "Hand-eye calibration") -> Path:
    """Write a PNG of the calibration to ``path`` (matplotlib, Agg backend); returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    inl, out = np.array(cal.inliers, dtype=int), np.array(cal.outliers, dtype=int)
    before_mm = 1e3 * (cal.mapped_start - cal.p_base)
    after_mm = 1e3 * (cal.mapped_base - cal.p_base)

    fig = plt.figure(figsize=(13, 11.5), layout="constrained")
    t_mm, ang = 1e3 * cal.T_flange_cam[:3, 3], np.degrees(rotation_angle(cal.T_flange_cam[:3, :3]))
    fig.suptitle(
        f"{title}: per-axis spread {np.round(cal.spread_mm, 1).tolist()} mm over inliers "
        f"({'PASS' if cal.passes else 'FAIL'}, limit {LAB_SPREAD_LIMIT_MM:.0f} mm)\n"
        f"{len(cal.inliers)} inliers, {len(cal.outliers)} outliers {cal.outliers or ''}; camera correction "
        f"{cal.correction.model}, depth scale {cal.correction.depth_scale:.4f}; T_flange_cam: "
        f"t = {np.round(t_mm, 1).tolist()} mm, rotation {ang:.1f} deg",
        fontsize=11,
    )
    before = "before (guess)" if cal.guess_given else "before (identity)"
    band = f"lab band, {LAB_SPREAD_LIMIT_MM:.0f} mm wide (+-{LAB_SPREAD_LIMIT_MM / 2:.0f} mm)"
    for axis in range(3):
        a = fig.add_subplot(3, 3, 1 + axis)  # before and after on one scale
        a.plot(inl, before_mm[inl, axis], "o", c="tab:grey", label=before)
        a.plot(inl, after_mm[inl, axis], "o", c="tab:blue", label="calibrated (after)")
        _axis_labels(a, axis, f"{'xyz'[axis]} of the mapped blob, before and after")
        if axis == 0:
            a.legend(fontsize=8)
        a = fig.add_subplot(3, 3, 4 + axis)  # the result alone, zoomed
        centre = 0.5 * (after_mm[inl, axis].max() + after_mm[inl, axis].min()) if inl.size else 0.0
        a.axhspan(centre - LAB_SPREAD_LIMIT_MM / 2, centre + LAB_SPREAD_LIMIT_MM / 2, color="tab:green",
                  alpha=0.15, label=band)  # fmt: skip
        a.plot(inl, after_mm[inl, axis], "o", c="tab:blue", label="inliers")
        if out.size:
            a.plot(out, after_mm[out, axis], "x", c="tab:red", ms=9, label="outliers")
        _axis_labels(a, axis, f"{'xyz'[axis]} after, zoomed (scale differs from above)")
        if axis == 0:
            a.legend(fontsize=8)
    _depth_residuals(fig.add_subplot(3, 3, (7, 8)), cal, inl, out)
    _pose_spread(fig.add_subplot(3, 3, 9), cal)
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
    ax.set_xlabel("measured depth z (m, camera frame)")
    ax.set_ylabel("depth residual (mm, camera z)")
    ax.set_title(
        f"residual vs depth ({cal.correction.model}, scale {cal.correction.depth_scale:.4f})", fontsize=9
    )
    ax.legend(fontsize=7)


def _axis_labels(ax, axis: int, title: str) -> None:  # type: ignore[no-untyped-def]
    from matplotlib.ticker import MaxNLocator

    ax.set_title(title, fontsize=10)
    ax.set_xlabel("sample (index)")
    ax.set_ylabel(f"{'xyz'[axis]} from the blob's estimate (mm, base frame)")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def _pose_spread(ax, cal: Calibration) -> None:  # type: ignore[no-untyped-def]
    """Each flange pose's rotation from the poses' mean orientation, as a rotation vector about the
    base axes (degrees): a calibration needs turns about at least two different axes."""
    from scipy.spatial.transform import Rotation

    R_base_flanges = Rotation.from_matrix(cal.T_base_flange[:, :3, :3])
    rotvecs_deg = np.degrees((R_base_flanges.mean().inv() * R_base_flanges).as_rotvec())  # (n, 3)
    for axis, marker in zip(range(3), "o^s", strict=True):
        ax.plot(np.arange(len(rotvecs_deg)), rotvecs_deg[:, axis], marker, label=f"about base {'xyz'[axis]}")
    ax.axhline(0.0, c="grey", lw=0.8)
    ax.set_title("how the poses turn: rotation from the mean pose", fontsize=9)
    ax.set_xlabel("sample (index)")
    ax.set_ylabel("rotation (deg)")
    ax.legend(fontsize=7)
