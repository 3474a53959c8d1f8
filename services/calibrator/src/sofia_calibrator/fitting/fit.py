"""A fit over a subset of the samples (transform, camera correction, noise) and what explains it."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy.special import stdtrit
from sofia_schemas.messages.calibration import CameraCorrection
from sofia_schemas.transforms import matrix_to_quat_xyzw, rpy_from_matrix

from . import correction as cc
from . import diagnostics as dg
from . import fit_kernels as fk
from . import kernels, so3
from . import uncertainty as uq
from .noise import NoiseModel, rms_mm
from .prior import ScalePrior, fit_with_prior
from .solver import Solution, refine, solve

_EYE4 = np.eye(4)
_EYE4.flags.writeable = False


@dataclass
class Fit:
    """One fit over a subset of the samples. ``T_flange_cam`` maps corrected camera points
    (``correction.apply(p_cam)``) into the flange frame."""

    T_flange_cam: np.ndarray  # (4, 4), metres
    p_base: np.ndarray  # (3,) blob in the base frame, metres
    samples: list[int]  # indices of the samples used
    mapped_base: np.ndarray  # (n_all, 3) every sample's corrected blob mapped into the base frame, metres
    mapped_start: np.ndarray  # (n_all, 3) the raw blob mapped through the guess (identity without one)
    residuals_mm: np.ndarray  # (n_all,) distance of each mapped blob to p_base, mm
    spread_mm: np.ndarray  # (3,) per-axis max - min over ``samples``, mm
    dissipation_before: float  # the lab's pairwise sum over ``samples`` at the start, metres
    dissipation_after: float
    std_translation_mm: np.ndarray  # (3,) flange axes
    std_rotation_deg: np.ndarray  # (3,) about the flange axes
    covariance: np.ndarray  # (9 + k, 9 + k) of (theta_cam, t_flange_cam, p_base, beta), noise estimated
    noise_scale: float  # fitted noise over what the camera model alone explains (1 = as modelled)
    n_iter: int
    correction: CameraCorrection = field(default_factory=CameraCorrection)
    covariance6: np.ndarray = field(default_factory=lambda: np.zeros((6, 6)))  # (t m, rot rad) flange axes
    noise_mm: float = float("nan")  # estimated 1-sigma per camera axis, RMS over the samples, mm
    camera_noise_mm: float = float("nan")  # the same of the camera model alone, mm
    sigma: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (n_all, 3) estimated noise, m
    solution: Solution | None = None

    @property
    def undetermined(self) -> str:
        """Why these samples cannot support the lab's verdict, '' when they can: no redundancy (the
        spread of a fit with no degrees of freedom left is zero by construction), or a translation
        1-sigma (flange axes) beyond the criterion's limit."""
        n_free = 3 * len(self.samples) - self.covariance.shape[0]
        if n_free <= 0:
            return f"{len(self.samples)} samples leave no redundancy, so the spread is not a measurement"
        worst = float(np.max(self.std_translation_mm))
        if not worst < dg.LAB_SPREAD_LIMIT_MM:
            return (
                f"the translation's 1-sigma {worst:.1f} mm is beyond the {dg.LAB_SPREAD_LIMIT_MM:.0f} mm "
                "limit, so the spread cannot show it is met"
            )
        return ""

    @property
    def passes(self) -> bool:
        """The lab's criterion (spread < 10 mm on every axis), False when :attr:`undetermined`."""
        return not self.undetermined and bool((self.spread_mm < dg.LAB_SPREAD_LIMIT_MM).all())

    @property
    def translation(self) -> np.ndarray:
        return np.asarray(self.T_flange_cam[:3, 3])

    @property
    def quaternion_xyzw(self) -> np.ndarray:
        return np.asarray(matrix_to_quat_xyzw(self.T_flange_cam[:3, :3]))

    @property
    def rpy(self) -> np.ndarray:
        return np.asarray(rpy_from_matrix(self.T_flange_cam[:3, :3]))

    def map_to_base(self, p_cam: np.ndarray, T_base_flange: np.ndarray) -> np.ndarray:
        """Measured blob/points into the base frame through the full chosen model.

        p_cam: (n, 3) measured, camera optical frame, metres; T_base_flange: (n, 4, 4) or (4, 4).
        Returns (n, 3) base frame, metres: T_base_flange T_flange_cam correction(p_cam).
        """
        p = self.correction.apply(np.asarray(p_cam, dtype=np.float64))
        T = np.broadcast_to(np.asarray(T_base_flange, dtype=np.float64), (len(p), 4, 4))
        return dg.map_to_base(T, self.T_flange_cam, p)


@dataclass
class Selection:
    """The chosen solution of a subset, the candidates compared, why, and the noise estimated."""

    solution: Solution
    candidates: list[cc.Candidate]
    reason: str
    noise: NoiseModel
    other_models9: np.ndarray = field(default_factory=lambda: np.zeros((9, 9)))  # weighted, of the others
    weight: float = 1.0  # weight of the chosen model (:func:`uncertainty.model_weights`)
    reference_errors: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (m, 3) rigid fit, m


@dataclass
class Problem:
    p_cam: np.ndarray  # (n, 3) measured, camera frame
    T_base_flange: np.ndarray  # (n, 4, 4)
    noise: NoiseModel
    guess: np.ndarray | None
    loss: str
    loss_scale: float
    models: tuple[str, ...] = cc.AUTO_MODELS  # the first is the reference (rigid)
    camera: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (n, 3) camera-model sigma
    prior: ScalePrior | None = None  # the depth scale of an earlier calibration (models: rigid, depth_scale)

    def solve(self, idx: np.ndarray, model: str, sigma: np.ndarray, start: Solution | None) -> Solution:
        """The ``model`` solution of samples ``idx``: warm from ``start``, else from every start."""
        p, T = self.p_cam[idx], self.T_base_flange[idx]
        if start is None:
            return solve(p, T, sigma, self.guess, self.loss, self.loss_scale, model=model)
        beta = start.beta if start.model == model else None
        return refine(p, T[:, :3, :3], T[:, :3, 3], sigma, start.R, start.t, start.p_base, self.loss,
                      self.loss_scale, model=model, beta=beta)  # fmt: skip

    def select(self, idx: np.ndarray, start: Solution | None = None) -> Selection:
        """Fit the models on samples ``idx`` with the noise level estimated from the data, and choose.

        The reference (rigid) fit gives the residuals the noise level is estimated from; under that
        noise every model's chi-square comes from one Gauss-Newton step from the reference optimum
        (exact for a linear model; the corrections are linear in their unknowns), the F-test
        (:func:`sofia_calibrator.fitting.correction.choose`) picks one, and only that one is refined.
        """
        m = len(idx)
        sigma0 = self.noise.sigma(idx)
        ref = self.solve(idx, self.models[0], sigma0, start)
        noise = self.noise.estimated(ref.errors, idx, 3 * m - 9 - cc.N_EXTRA[self.models[0]])
        sigma = noise.sigma(idx)
        models = self.models if m >= cc.MIN_SAMPLES_FOR_SCALE or self.prior else self.models[:1]
        p, T = self.p_cam[idx], self.T_base_flange[idx]
        ks = [cc.N_EXTRA[mo] for mo in models]
        assert ref.J is not None
        G = np.concatenate([cc.columns(mo, p) for mo in models], axis=2)
        chi2, dx, beta, cov9, beta_sigma = fk.gauss_newton_steps(
            ref.J, ref.errors, sigma0, sigma, G, np.array(ks, dtype=np.int64)
        )
        cands = [
            cc.Candidate(mo, float(chi2[b]), 9 + kb, 3 * m, beta[b, :kb], beta_sigma[b, :kb] if kb else None)
            for b, (mo, kb) in enumerate(zip(models, ks, strict=True))
        ]
        chosen, reason = cc.choose(cands) if len(cands) > 1 else (cands[0], f"{cands[0].model} (as asked)")
        if self.prior is not None:
            sel = self._with_prior(cands, dx, ref, p, T, sigma, noise)
            if sel.solution is not ref:
                return sel
            if m < cc.MIN_SAMPLES_FOR_SCALE:  # unused: as without a prior, the scale is not tried
                cands, dx = cands[:1], dx[:1]
                chosen, reason = cands[0], f"{cands[0].model} (as asked)"
            reason = f"{reason} ({sel.reason})"
        k = cands.index(chosen)
        sol = refine(p, T[:, :3, :3], T[:, :3, 3], sigma, ref.R @ so3.exp(dx[k, :3]), ref.t + dx[k, 3:6],
                     ref.p_base + dx[k, 6:9], self.loss, self.loss_scale, model=chosen.model, beta=chosen.beta)  # fmt: skip
        chosen.chi2, chosen.beta = sol.cost, sol.beta
        # the plausible models' spread (see :mod:`sofia_calibrator.fitting.uncertainty`)
        w = uq.model_weights([c.chi2 for c in cands], 3 * m)
        extra = np.zeros((9, 9))
        for b in range(len(cands)):
            if b != k and w[b] > 0.0:
                d = dx[b] - dx[k]
                extra += w[b] * (cov9[b] + uq.SELECTION_WIDENING * d[:, None] * d)
        return Selection(sol, cands, reason, noise, extra, w[k], ref.errors)

    def _with_prior(self, cands: list[cc.Candidate], dx: np.ndarray, ref: Solution, p: np.ndarray,
                    T: np.ndarray, sigma: np.ndarray, noise: NoiseModel) -> Selection:  # fmt: skip
        """The depth-scale fit under ``self.prior`` (:func:`fit_with_prior`), or the reference fit
        carrying the reason when the prior is not used."""
        assert self.prior is not None
        k, c = len(cands) - 1, cands[-1]
        data = refine(p, T[:, :3, :3], T[:, :3, 3], sigma, ref.R @ so3.exp(dx[k, :3]), ref.t + dx[k, 3:6],
                      ref.p_base + dx[k, 6:9], self.loss, self.loss_scale, model=c.model, beta=c.beta)  # fmt: skip
        sol, reason = fit_with_prior(data, self.prior, p, T, sigma, self.loss, self.loss_scale)
        if sol is None:
            return Selection(ref, cands, reason, noise)
        c.chi2, c.beta = sol.cost, sol.beta
        return Selection(sol, cands, reason, noise, np.zeros((9, 9)), 1.0, ref.errors)

    def explain(self, idx: np.ndarray, sel: Selection) -> Fit:
        """The :class:`Fit` of a selection over samples ``idx``."""
        sol, noise = sel.solution, sel.noise
        T_fc = sol.T_flange_cam
        corr_p = cc.apply(sol.model, sol.beta, self.p_cam)
        mapped = dg.map_to_base(self.T_base_flange, T_fc, corr_p)
        d = mapped - sol.p_base
        T0 = _EYE4 if self.guess is None else self.guess
        mapped_start = dg.map_to_base(self.T_base_flange, T0, self.p_cam)
        dof = 3 * len(idx) - 9 - len(sol.beta)
        scale2 = sol.cost / dof if dof > 0 else 1.0
        by_axis = uq.parameter_covariance(sol, noise, idx) if dof > 0 else None
        cov = kernels.inverse(sol.JtJ) * scale2 if by_axis is None else by_axis
        cov[:9, :9] = sel.weight * cov[:9, :9] + sel.other_models9
        cov *= t_inflation(dof)
        cov6 = dg.covariance6(sol.R, cov)
        std_t, std_r = dg.std_from_covariance6(cov6)
        beta_sigma = np.sqrt(np.maximum(cov.diagonal()[9:], 0.0)) if len(sol.beta) else None
        sigma_all = noise.sigma() * np.sqrt(scale2)
        noise_mm, cam_mm = rms_mm(sigma_all[idx]), rms_mm(self.camera[idx])
        return Fit(
            T_flange_cam=T_fc, p_base=sol.p_base, samples=idx.tolist(), mapped_base=mapped,
            mapped_start=mapped_start, residuals_mm=1e3 * np.sqrt(np.einsum("ij,ij->i", d, d)),
            spread_mm=1e3 * dg.spread(mapped[idx]), dissipation_before=dg.dissipation(mapped_start[idx]),
            dissipation_after=dg.dissipation(mapped[idx]), std_translation_mm=std_t,
            std_rotation_deg=std_r, covariance=cov, noise_scale=noise_mm / max(cam_mm, 1e-9),
            n_iter=sol.n_iter, correction=cc.message(sol.model, sol.beta, beta_sigma),
            covariance6=cov6, noise_mm=noise_mm, camera_noise_mm=cam_mm,
            sigma=sigma_all, solution=sol,
        )  # fmt: skip


@lru_cache(maxsize=64)
def t_inflation(dof: int) -> float:
    """Factor on a covariance whose noise level was estimated with ``dof`` degrees of freedom, so
    that its 1-sigma is the 68.3 % Student-t half-width (1 for unknown dof)."""
    return float(stdtrit(dof, 0.8413447460685429) ** 2) if dof > 0 else 1.0
