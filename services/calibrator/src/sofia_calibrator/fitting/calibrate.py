"""``calibrate``: validated inputs in, a self-explaining :class:`Calibration` out."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from sofia_schemas.frames import CAMERA_FRAME, FLANGE_FRAME
from sofia_schemas.transforms import ORTHONORMAL_TOL, as_points, as_transforms

from ..errors import InputMismatch, TooFewSamples
from . import correction as cc
from . import diagnostics as dg
from . import kernels
from .advice import criterion_advice, noise_warning, redundancy_warning
from .fit import Fit, Problem, Selection
from .influence import Influence, influence
from .noise import ISOTROPIC_PRIOR_M, NoiseModel, camera_sigma
from .prior import ScalePrior
from .screen import gross_errors
from .solver import LOSSES

MIN_SAMPLES = 3
PARENT_FRAME = FLANGE_FRAME  # the lab's launch file: flange
CHILD_FRAME = CAMERA_FRAME
LOSS_SCALE = 3.0  # of the robust losses, in sigma units
MAX_ADVICE = 5  # at most this many samples named as the removal that would meet the lab criterion


@dataclass
class Calibration(Fit):
    """The chosen fit plus what explains it: outliers, leave-one-out residuals, the other fit, the
    correction models compared. ``map_to_base(p_cam, T_base_flange)`` applies the full model."""

    inliers: list[int] = field(default_factory=list)
    outliers: list[int] = field(default_factory=list)
    leave_one_out_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    warnings: list[str] = field(default_factory=list)
    with_all_samples: Fit | None = None  # set when outliers were excluded
    without_outliers: Fit | None = None  # set when outliers were found but kept
    p_cam: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    T_base_flange: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    candidates: list[cc.Candidate] = field(default_factory=list)  # correction models compared
    correction_reason: str = ""
    criterion_advice: list[int] = field(default_factory=list)  # removal that would meet the criterion
    parent_frame: str = PARENT_FRAME
    child_frame: str = CHILD_FRAME
    guess_given: bool = False  # mapped_start is through the guess (else the identity)
    # (n, 3) measured minus predicted blob of the reference (rigid) fit, camera frame, mm (NaN: not fitted)
    reference_residuals_mm: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def _validate(
    p_cam: np.ndarray, T_base_flange: np.ndarray, guess: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    p = as_points(p_cam, "p_cam")
    T = np.asarray(T_base_flange, dtype=np.float64)
    # valid poses (checked at half the tolerance, compiled) skip the numpy validation; anything
    # else, borderline ones included, goes through it for the verdict and the message
    fast = T.ndim == 3 and T.shape[1:] == (4, 4)
    if not (fast and kernels.rigid_transforms(kernels.c_array(T), 0.5 * ORTHONORMAL_TOL)):
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
    g = None if guess is None else as_transforms(guess, "guess (T_flange_cam)")
    if g is not None and g.ndim != 2:
        raise InputMismatch(f"guess must be one (4, 4) T_flange_cam, got {g.shape}")
    return p, T, g


def _noise(p: np.ndarray, sigma: object, confidence: np.ndarray | None, camera: np.ndarray) -> NoiseModel:
    """The noise model of the ``sigma`` option (see :func:`calibrate`), divided by ``confidence``.
    camera: (n, 3) the camera model's 1-sigma of the samples ``p`` (:func:`camera_sigma`), metres."""
    if sigma is None or (isinstance(sigma, str) and sigma == "auto"):
        model = NoiseModel(camera, True, ISOTROPIC_PRIOR_M)
    elif isinstance(sigma, str) and sigma == "depth":
        model = NoiseModel(camera, False, 1.0)
    elif isinstance(sigma, str) and sigma == "uniform":
        model = NoiseModel(np.full_like(p, 1e-3), False, 1.0)
    elif isinstance(sigma, str):
        raise InputMismatch(f"sigma must be 'auto', 'depth', 'uniform' or an array, got {sigma!r}")
    else:
        try:
            s = np.broadcast_to(np.asarray(sigma, dtype=np.float64).reshape(len(p), -1), p.shape).copy()
        except ValueError:
            raise InputMismatch(f"sigma must be (n, 3) or (n,) for n = {len(p)} samples, got "
                                f"{np.asarray(sigma).shape}") from None  # fmt: skip
        if not np.all(np.isfinite(s) & (s > 0)):
            raise InputMismatch(f"sigma must be finite and positive, got {s.tolist()}")
        model = NoiseModel(s, False, 1.0)
    if confidence is None:
        return model
    c = np.asarray(confidence, dtype=np.float64).reshape(-1)
    if c.shape != (len(p),) or not np.all(np.isfinite(c) & (c > 0) & (c <= 1)):
        raise InputMismatch(f"confidence must be (n,) = ({len(p)},) values in (0, 1], got {c.tolist()}")
    return replace(model, base=model.base / np.clip(c, 0.05, 1.0)[:, None])


def _prior(prior: ScalePrior | tuple[float, float] | None, correction: str) -> ScalePrior | None:
    """The :class:`ScalePrior` of the ``depth_scale_prior`` option, with ``correction`` checked."""
    if correction != "auto" and correction not in cc.MODELS:
        raise InputMismatch(f"correction must be 'auto' or one of {cc.MODELS}, got {correction!r}")
    if prior is None or isinstance(prior, ScalePrior):
        out = prior
    else:
        try:
            scale, sigma = (float(x) for x in prior)
        except (TypeError, ValueError):
            raise InputMismatch(f"depth_scale_prior must be (scale, sigma), got {prior!r}") from None
        out = ScalePrior(scale, sigma)
    if out is not None and correction not in ("auto", "depth_scale"):
        raise InputMismatch(
            f"a depth-scale prior needs correction 'auto' or 'depth_scale', got {correction!r}"
        )
    return out


def _loo_mm(sel: Selection, idx: np.ndarray, residuals_mm: np.ndarray, inf: Influence | None) -> np.ndarray:
    """(n_all,) leave-one-out prediction error of each sample, mm (hat matrix for the samples of
    the fit; the plain residual for the others, which the fit did not use). ``inf``: the selection's
    influence when already computed."""
    loo = residuals_mm.copy()
    if 3 * len(idx) - sel.solution.JtJ.shape[0] > 0:
        d = (inf or influence(sel.solution)).loo_whitened * sel.noise.sigma(idx)
        loo[idx] = 1e3 * np.linalg.norm(d, axis=1)
    return loo


def calibrate(
    p_cam: np.ndarray,
    T_base_flange: np.ndarray,
    *,
    guess: np.ndarray | None = None,
    sigma: np.ndarray | Literal["auto", "depth", "uniform"] | None = None,
    loss: str = "linear",
    exclude_outliers: bool = True,
    enforce_criterion: bool = True,
    leave_one_out: bool = True,
    correction: str = "auto",
    confidence: np.ndarray | None = None,
    depth_scale_prior: ScalePrior | tuple[float, float] | None = None,
    parent_frame: str = PARENT_FRAME,
    child_frame: str = CHILD_FRAME,
) -> Calibration:
    """Hand-eye calibration from a blob fixed in the world, seen from n flange poses.

    p_cam: (n, 3) blob, camera optical frame, metres. T_base_flange: (n, 4, 4) flange poses
    (panda_link0 -> panda_link8) in the base frame. guess: optional (4, 4) T_flange_cam, one more
    start beside the closed form (never required). loss: "linear", "huber" or "cauchy" (scale
    ``LOSS_SCALE``). sigma: the noise model; its level is always estimated from the residuals. "auto" (default,
    None): an isotropic component (robot, blob extraction) added to the D435 model; "depth": the
    D435 model times a factor; "uniform": isotropic; an (n, 3) or (n,) array (metres): relative
    weights times a factor. confidence: optional (n,) in (0, 1] dividing each sample's sigma.
    correction: "auto" chooses rigid or depth_scale by an F-test (``correction.MODEL_ALPHA``); or
    one of rigid, depth_scale, ray_scale. depth_scale_prior: (scale, 1-sigma) of an earlier
    calibration of the same camera, or a :class:`ScalePrior`: the depth scale is then fitted with it
    as a prior (:mod:`sofia_calibrator.fitting.prior`), no test; correction must be auto or depth_scale.

    Outliers: the studentized leave-one-out test (F(3, dof - 3), family-wise false-alarm rate
    ``diagnostics.OUTLIER_ALPHA``), worst first, under the chosen correction, among the gross errors of a
    robust fit (:mod:`sofia_calibrator.fitting.screen`: heavy-tailed noise does not make outliers). exclude_outliers: the returned
    fit leaves them out (``with_all_samples`` keeps the other fit); else it keeps them
    (``without_outliers``). The lab's 1 cm criterion never removes samples: when it fails and
    ``enforce_criterion``, ``criterion_advice`` names the fewest samples whose removal would meet it.
    leave_one_out: per-sample prediction errors from the hat matrix (one fit, no refits).
    Returns a :class:`Calibration`; ``T_flange_cam`` maps corrected camera points into the flange.
    """
    if loss not in LOSSES:
        raise InputMismatch(f"loss must be one of {LOSSES}, got {loss!r}")
    p, T, g = _validate(p_cam, T_base_flange, guess)
    camera = camera_sigma(p)
    noise = _noise(p, sigma, confidence, camera)
    warnings = dg.check_motion(T)
    prior = _prior(depth_scale_prior, correction)
    models = cc.AUTO_MODELS if correction == "auto" else (correction,)
    prob = Problem(p, T, noise, g, loss, LOSS_SCALE, models, camera, prior)
    n = len(p)
    idx = np.arange(n)
    sel_all = prob.select(idx)
    sel, kept, outliers = sel_all, idx, []
    keep_min = max(MIN_SAMPLES + 3, (n + 1) // 2)
    # the influence of sel_all and of the current sel, held with them (never keyed by id(): a freed
    # selection's id is reused by the next one, whose samples differ)
    inf_all: Influence | None = None
    inf_sel: Influence | None = None
    # only a gross error of a robust fit may be removed (heavy-tailed noise: see screen.py)
    gross = gross_errors(p, T, noise.sigma(), dg.OUTLIER_ALPHA) if len(kept) > keep_min else np.zeros(n, bool)
    while len(kept) > keep_min and gross[kept].any():
        inf_sel = influence(sel.solution)
        inf_all = inf_sel if sel is sel_all else inf_all
        pv = np.where(np.isnan(inf_sel.p_value) | ~gross[kept], np.inf, inf_sel.p_value)
        k = int(pv.argmin())
        if not pv[k] < dg.OUTLIER_ALPHA / len(kept):
            break
        outliers.append(int(kept[k]))
        kept = np.delete(kept, k)
        sel, inf_sel = prob.select(kept, start=sel.solution), None
    everything = prob.explain(idx, sel_all)
    cleaned = prob.explain(kept, sel) if outliers else everything
    chosen, chosen_sel = (cleaned, sel) if exclude_outliers else (everything, sel_all)
    chosen_idx = kept if exclude_outliers else idx  # chosen.samples
    loo = chosen.residuals_mm
    if leave_one_out:
        loo = _loo_mm(
            chosen_sel, chosen_idx, chosen.residuals_mm, inf_all if chosen_sel is sel_all else inf_sel
        )
    ref_mm = np.full((n, 3), np.nan)
    ref_mm[chosen_idx] = -1e3 * chosen_sel.reference_errors
    advice: list[int] = []
    passes = chosen.passes
    if not passes and enforce_criterion and len(chosen_idx) >= MIN_SAMPLES + 3:
        advice = criterion_advice(prob, chosen_sel, chosen_idx, max(1, min(len(chosen_idx) // 5, MAX_ADVICE)))
    warnings += redundancy_warning(chosen, T)
    warnings += noise_warning(chosen)
    if outliers:
        verb = "excluded" if exclude_outliers else "kept (exclude_outliers=False)"
        names = ", ".join(f"{i} ({everything.residuals_mm[i]:.1f} mm)" for i in outliers)
        noun, be = ("sample", "is a") if len(outliers) == 1 else ("samples", "are")
        warnings.append(
            f"{noun} {names} {be} clear outlier{'s' * (len(outliers) > 1)} by the leave-one-out test "
            f"under the {chosen.correction.model} model and {'was' if len(outliers) == 1 else 'were'} {verb}"
        )
        warnings.append(
            f"per-axis spread with every sample {np.round(everything.spread_mm, 1).tolist()} mm, without "
            f"samples {outliers} {np.round(cleaned.spread_mm, 1).tolist()} mm"
        )
    if chosen.undetermined:
        warnings.append(
            f"the lab criterion is undetermined (passes is false): {chosen.undetermined}; add poses"
        )
    elif not passes:
        worst = chosen.samples[int(np.argmax(loo[chosen_idx]))]
        tail = (
            f"removing samples {advice} would meet it (advice only: nothing was removed)"
            if advice else f"sample {worst} agrees least with the others ({loo[worst]:.1f} mm leave-one-out)"
        )  # fmt: skip
        warnings.append(
            f"the lab criterion fails: per-axis spread {np.round(chosen.spread_mm, 1).tolist()} mm "
            f"(limit {dg.LAB_SPREAD_LIMIT_MM:.0f} mm); {tail}: re-record it or add poses"
        )
    return Calibration(
        **vars(chosen),
        inliers=chosen.samples, outliers=outliers, leave_one_out_mm=loo, warnings=warnings,
        with_all_samples=everything if (outliers and exclude_outliers) else None,
        without_outliers=cleaned if (outliers and not exclude_outliers) else None,
        p_cam=p, T_base_flange=T, candidates=sel_all.candidates if not exclude_outliers else sel.candidates,
        correction_reason=(sel if exclude_outliers else sel_all).reason, criterion_advice=advice,
        parent_frame=parent_frame, child_frame=child_frame, guess_given=g is not None, reference_residuals_mm=ref_mm,
    )  # fmt: skip
