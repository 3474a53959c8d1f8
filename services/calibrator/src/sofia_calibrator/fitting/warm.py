"""Compiling the fit's numba kernels ahead of the first calibration (the install step, the images)."""

from __future__ import annotations

import numpy as np

from .calibrate import calibrate
from .simulate import make_problem
from .so3 import exp, log


def warm_kernels() -> None:
    """Compile every kernel (or load it from numba's cache) on small synthetic problems, so that
    the first calibration does not wait for it: the default calibration, a robust one, the
    multi-start of a 4-sample set, and the SO(3) helpers."""
    rng = np.random.default_rng(0)
    pr = make_problem(12, rng, robot_noise_m=0.001, depth_scale=0.97)
    calibrate(pr.p_cam, pr.T_base_flange)
    calibrate(pr.p_cam, pr.T_base_flange, loss="huber", guess=pr.T_flange_cam)
    few = make_problem(4, rng)
    calibrate(few.p_cam, few.T_base_flange)
    log(exp(np.array([0.1, 0.2, 0.3])))
