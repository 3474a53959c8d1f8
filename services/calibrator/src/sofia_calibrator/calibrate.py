"""``calibrate``: validated inputs in, a self-explaining :class:`Calibration` out."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from sofia_schemas.transforms import as_points, as_transforms

from . import diagnostics as dg
from .errors import InputMismatch, TooFewSamples
from .fit import Fit, Problem, warm_start
from .noise import camera_sigma
from .solver import LOSSES

MIN_SAMPLES = 3


@dataclass
class Calibration(Fit):
    """The chosen fit plus what explains it: outliers, leave-one-out residuals, the other fit."""

    inliers: list[int] = field(default_factory=list)
    outliers: list[int] = field(default_factory=list)
    leave_one_out_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    warnings: list[str] = field(default_factory=list)
    with_all_samples: Fit | None = None  # set when outliers were excluded
    without_outliers: Fit | None = None  # set when outliers were found but kept
    p_cam: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    T_base_flange: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))


def _validate(
    p_cam: np.ndarray, T_base_flange: np.ndarray, sigma: np.ndarray | str | None, guess: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    p = as_points(p_cam, "p_cam")
    T = as_transforms(T_base_flange, "T_base_flange")
    if T.ndim != 3:
        raise InputMismatch(f"T_base_flange must be (n, 4, 4), got {T.shape}")
    if len(p) != len(T):
        raise InputMismatch(f"{len(p)} blob positions (p_cam) but {len(T)} flange poses (T_base_flange)")
    if len(p) < MIN_SAMPLES:
        raise TooFewSamples(len(p), MIN_SAMPLES)
    behind = np.flatnonzero(p[:, 2] <= 0.0)
    if behind.size:
        raise InputMismatch(
            f"p_cam rows {behind.tolist()} have z <= 0 (z = {p[behind, 2].tolist()}): the camera optical "
            "frame looks along +z, so the blob must be in front of the camera"
        )
    if sigma is None or (isinstance(sigma, str) and sigma == "depth"):
        s = camera_sigma(p)
    elif isinstance(sigma, str) and sigma == "uniform":
        s = np.full_like(p, 1e-3)
    elif isinstance(sigma, str):
        raise InputMismatch(f"sigma must be 'depth', 'uniform' or an array, got {sigma!r}")
    else:
        s = np.broadcast_to(np.asarray(sigma, dtype=np.float64).reshape(len(p), -1), p.shape).copy()
        if not np.all(np.isfinite(s) & (s > 0)):
            raise InputMismatch(f"sigma must be finite and positive, got {s.tolist()}")
    g = None if guess is None else as_transforms(guess, "guess (T_flange_cam)")
    if g is not None and g.ndim != 2:
        raise InputMismatch(f"guess must be one (4, 4) T_flange_cam, got {g.shape}")
    return p, T, s, g


def _leave_one_out(prob: Problem, idx: list[int], start: Fit) -> list[Fit]:
    """Fits without each sample of ``idx`` in turn, warm-started from ``start``."""
    members = np.array(idx)
    return [prob.fit(members[members != i], start=warm_start(start))[0] for i in idx]


def _clear_outliers(prob: Problem, fit: Fit, alpha: float, keep_min: int) -> tuple[list[int], Fit]:
    """Clear outliers, worst first: both the sample's residual and its leave-one-out residual (from a
    fit without it) are beyond the chi-square limit of the noise scale of the other samples."""
    outliers: list[int] = []
    while len(fit.samples) > keep_min:
        inl = np.array(fit.samples)
        w = prob.whitened(fit)[inl]
        k = int(np.argmax(w))
        if dg.outlier_ratio(w[k : k + 1], np.delete(w, k), alpha)[0] <= 1.0:
            break
        rest = np.delete(inl, k)
        fit_rest = prob.fit(rest, start=warm_start(fit))[0]
        w_rest = prob.whitened(fit_rest)
        if dg.outlier_ratio(w_rest[inl[k : k + 1]], w_rest[rest], alpha)[0] <= 1.0:
            break
        outliers.append(int(inl[k]))
        fit = fit_rest
    return outliers, fit


def _criterion_outliers(fit: Fit, prob: Problem, max_remove: int) -> tuple[list[int], Fit]:
    """The fewest samples (greedy, at most ``max_remove``) whose removal makes the fit meet the lab's
    criterion; none when that is not enough."""
    removed: list[int] = []
    while not fit.passes and len(removed) < max_remove:
        fits = _leave_one_out(prob, fit.samples, fit)
        k = int(np.argmin([f.spread_mm.max() for f in fits]))
        removed.append(fit.samples[k])
        fit = fits[k]
    return (removed, fit) if fit.passes else ([], fit)


def calibrate(
    p_cam: np.ndarray,
    T_base_flange: np.ndarray,
    *,
    guess: np.ndarray | None = None,
    sigma: np.ndarray | Literal["depth", "uniform"] | None = None,
    loss: str = "linear",
    loss_scale: float = 3.0,
    exclude_outliers: bool = True,
    outlier_alpha: float = dg.OUTLIER_ALPHA,
    enforce_criterion: bool = True,
    leave_one_out: bool = True,
) -> Calibration:
    """Hand-eye calibration from a blob fixed in the world, seen from n flange poses.

    p_cam: (n, 3) blob, camera optical frame, metres. T_base_flange: (n, 4, 4) flange poses in the
    base frame. guess: optional (4, 4) T_flange_cam start (never required: a closed-form linear
    solution starts the refinement). sigma: per-sample camera-frame noise, (n, 3) or (n,) metres,
    "depth" (default: D435 model, depth noise ~ z^2) or "uniform" (1 mm).
    loss: "linear", "huber" or "cauchy" (scale in sigma units).

    Outliers are clear robust-statistics outliers (the residual and the leave-one-out residual
    both beyond the chi-square limit of the median-estimated noise scale, family-wise false-alarm
    rate ``outlier_alpha``) and, when ``enforce_criterion`` and the fit fails
    the lab's 1 cm criterion, the fewest samples (at most a fifth) whose removal makes it pass.
    exclude_outliers: the returned fit leaves them out (the fit with every sample stays in
    ``with_all_samples``); otherwise it keeps them (``without_outliers`` holds the other fit).
    Returns a :class:`Calibration`; its ``T_flange_cam`` maps camera points into the flange frame.
    """
    if loss not in LOSSES:
        raise InputMismatch(f"loss must be one of {LOSSES}, got {loss!r}")
    p, T, s, g = _validate(p_cam, T_base_flange, sigma, guess)
    warnings = dg.check_motion(T)
    prob = Problem(p, T, s, g, loss, loss_scale)
    n = len(p)
    everything = prob.fit(np.arange(n))[0]
    keep_min = max(MIN_SAMPLES + 2, (n + 1) // 2)
    clear, cleaned = _clear_outliers(prob, everything, outlier_alpha, keep_min)
    crit: list[int] = []
    if enforce_criterion and not cleaned.passes and n >= MIN_SAMPLES + 3:
        crit, cleaned = _criterion_outliers(cleaned, prob, max(1, n // 5))
    outliers = clear + crit
    chosen = cleaned if exclude_outliers else everything
    if chosen is not everything:  # refit from the start, so that "before" is the guess or linear start
        chosen = prob.fit(np.array(chosen.samples))[0]
    loo = chosen.residuals_mm.copy()
    if leave_one_out and len(chosen.samples) > MIN_SAMPLES + 1:
        for i, f in zip(chosen.samples, _leave_one_out(prob, chosen.samples, chosen), strict=True):
            loo[i] = f.residuals_mm[i]
    if 3 * len(chosen.samples) - 9 <= 0:
        warnings.append(
            f"{len(chosen.samples)} samples leave no redundancy: the uncertainty is the modelled noise, "
            "not measured; add samples"
        )
    verb = "excluded" if exclude_outliers else "kept (exclude_outliers=False)"
    for kind, group in (
        ("clear outlier(s) by robust statistics", clear),
        ("the cause of the failed lab criterion", crit),
    ):
        if group:
            names = ", ".join(f"{i} ({everything.residuals_mm[i]:.1f} mm)" for i in group)
            noun, be = ("sample", "is") if len(group) == 1 else ("samples", "are")
            warnings.append(f"{noun} {names} {be} {kind} and {'was' if len(group) == 1 else 'were'} {verb}")
    if outliers:
        warnings.append(
            f"per-axis spread with every sample {np.round(everything.spread_mm, 1).tolist()} mm, without "
            f"samples {outliers} {np.round(cleaned.spread_mm, 1).tolist()} mm"
        )
    if not chosen.passes:
        worst = chosen.samples[int(np.argmax(loo[chosen.samples]))]
        warnings.append(
            f"the lab criterion fails: per-axis spread {np.round(chosen.spread_mm, 1).tolist()} mm "
            f"(limit {dg.LAB_SPREAD_LIMIT_MM:.0f} mm); sample {worst} agrees least with the others "
            f"({loo[worst]:.1f} mm leave-one-out): re-record it or add poses"
        )
    return Calibration(
        **{k: getattr(chosen, k) for k in Fit.__dataclass_fields__},
        inliers=chosen.samples, outliers=outliers, leave_one_out_mm=loo, warnings=warnings,
        with_all_samples=everything if (outliers and exclude_outliers) else None,
        without_outliers=cleaned if (outliers and not exclude_outliers) else None,
        p_cam=p, T_base_flange=T,
    )  # fmt: skip
