"""Camera-correction models fitted jointly with ``T_flange_cam``, and the choice between them.

A D435's depth is often off by a scale of 1-5 %. The measured blob ``p_cam`` (camera optical frame,
metres) is corrected before the rigid transform, linearly in the unknowns ``beta``: ``p_corr =
p_cam + G(p_cam) @ beta``. ``rigid``: none (k = 0); ``depth_scale``: z times s = 1 + beta[0] (G =
(0, 0, z)); ``ray_scale``: the whole point times s (G = p). No constant depth offset: for a blob
seen straight ahead it is the camera moving along its z axis, which ``T_flange_cam`` already does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import fdtrc
from sofia_schemas.messages.calibration import CameraCorrection

from ..errors import InputMismatch

MODELS = ("rigid", "depth_scale", "ray_scale")
# The models ``correction="auto"`` chooses between. A D435's error is in its depth (stereo
# disparity), and real data favour the depth-only scale: offering ray_scale as well let the test
# pick it on a single leave-one-out fold of the lab's 11 samples (6.3 mm prediction error there,
# leave-one-out RMS 2.89 instead of 2.38 mm). ray_scale stays available when asked for.
AUTO_MODELS = ("rigid", "depth_scale")
N_EXTRA = {"rigid": 0, "depth_scale": 1, "ray_scale": 1}
# A correction is chosen when the F-test against the rigid model rejects rigid at this level
# (Bonferroni over the corrections tried). Measured (bench/bench_calibrator_targets.py): 0.003
# keeps the unbiased synthetic RMS within 1.2 % of the rigid maximum-likelihood fit at n = 8-20
# while 6-7-sample subsets of the lab set get their depth scale 2-3x as often as at 0.001
# (held-out prediction RMS 4.1 / 3.0 mm instead of 4.4 / 3.8 mm; rigid alone: 4.9 / 4.7 mm).
MODEL_ALPHA = 0.003
MIN_SAMPLES_FOR_SCALE = 6  # below this the scale is not separable from the transform with any redundancy


def columns(model: str, p_cam: np.ndarray) -> np.ndarray:
    """(n, 3, k) d p_corr / d beta of (n, 3) camera-frame points for ``model``."""
    n = len(p_cam)
    G = np.zeros((n, 3, N_EXTRA[model]))
    if model == "depth_scale":
        G[:, 2, 0] = p_cam[:, 2]
    elif model == "ray_scale":
        G[:, :, 0] = p_cam
    return G


def apply(model: str, beta: np.ndarray, p_cam: np.ndarray) -> np.ndarray:
    """(n, 3) corrected camera-frame points: ``p_cam + G(p_cam) @ beta``."""
    if model == "rigid":
        return p_cam
    return p_cam + columns(model, p_cam) @ beta


def message(model: str, beta: np.ndarray, beta_sigma: np.ndarray | None) -> CameraCorrection:
    """The bus message of a fitted correction (scale = 1 + beta[0])."""
    if model == "rigid":
        return CameraCorrection()
    sig = None if beta_sigma is None else float(beta_sigma[0])
    if not 1.0 + float(beta[0]) > 0.0:
        raise InputMismatch(
            f"the fitted {model} came out {1.0 + float(beta[0]):.3f}, not a scale: the views do not "
            "constrain it (too few, too alike, or depths that disagree); calibrate with correction 'rigid', "
            "or add views"
        )
    return CameraCorrection(model=model, depth_scale=1.0 + float(beta[0]), depth_scale_sigma=sig)  # type: ignore[arg-type]


@dataclass
class Candidate:
    """A fitted model for the choice: chi-square in nominal noise units, unknowns, observations."""

    model: str
    chi2: float
    n_params: int
    n_obs: int
    beta: np.ndarray
    beta_sigma: np.ndarray | None
    p_value: float | None = None

    @property
    def aic(self) -> float:
        return self.n_obs * math.log(max(self.chi2, 1e-300) / self.n_obs) + 2 * self.n_params


def choose(cands: list[Candidate], alpha: float = MODEL_ALPHA) -> tuple[Candidate, str]:
    """The chosen model and why. ``cands[0]`` is rigid; the best-fitting correction replaces it when
    the F-test (nested, one more unknown) rejects the rigid model at ``alpha``; p-values are set."""
    rigid = cands[0]
    for c in cands[1:]:
        dof = c.n_obs - c.n_params
        if dof <= 0:
            continue
        extra = c.n_params - rigid.n_params
        F = max(rigid.chi2 - c.chi2, 0.0) / extra / max(c.chi2 / dof, 1e-300)
        c.p_value = float(fdtrc(extra, dof, F))
    tested = [c for c in cands[1:] if c.p_value is not None]
    if not tested:
        return rigid, "rigid: too few samples to test a depth-scale correction"
    best = min(tested, key=lambda c: c.chi2)
    assert best.p_value is not None
    daic = best.aic - rigid.aic
    if best.p_value * len(tested) < alpha:
        return (
            best,
            f"{best.model}: F-test against rigid p = {best.p_value:.2g} (< {alpha} / {len(tested)}), AIC {daic:+.1f}",
        )
    return (
        rigid,
        f"rigid: the best correction ({best.model}) is not significant (p = {best.p_value:.2g}, AIC {daic:+.1f})",
    )
