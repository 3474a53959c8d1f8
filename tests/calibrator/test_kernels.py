"""The compiled kernels against the numpy/scipy/LAPACK computations they replace."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_calibrator import calibrate
from sofia_calibrator.fitting import diagnostics, influence, kernels, noise, so3
from sofia_calibrator.fitting import fit_kernels as fk
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.fitting.warm import warm_kernels
from sofia_schemas.transforms import ORTHONORMAL_TOL, as_transforms


def _svd_projection(M: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    if np.linalg.det(U @ Vt) < 0:
        U[:, 2] = -U[:, 2]
    return np.asarray(U @ Vt)


def test_project_is_the_nearest_rotation_of_the_svd() -> None:
    rng = np.random.default_rng(0)
    for k in range(500):
        M = rng.normal(size=(3, 3)) * 10.0 ** rng.uniform(-3, 3)  # det < 0 about half the time
        if k % 2:
            M = so3.exp(rng.normal(size=3)) + 0.05 * rng.normal(size=(3, 3))
        R = so3.project(M)
        assert np.allclose(R, _svd_projection(M), atol=1e-11)
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-13) and np.linalg.det(R) > 0


def test_log_matches_scipy_up_to_pi() -> None:
    rng = np.random.default_rng(1)
    axes = rng.normal(size=(400, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.r_[rng.uniform(0, np.pi, 200), np.pi - rng.uniform(0, 2e-3, 199), 0.0]
    v = axes * angles[:, None]
    R = Rotation.from_rotvec(v).as_matrix()
    assert np.allclose(so3.log(R), Rotation.from_matrix(R).as_rotvec(), atol=1e-9)
    assert so3.log(R[:6].reshape(2, 3, 3, 3)).shape == (2, 3, 3)


def test_indefinite_solves_match_numpy() -> None:
    rng = np.random.default_rng(2)
    for p in (3, 9, 11, 15):
        Q = np.linalg.qr(rng.normal(size=(p, p)))[0]
        S = (Q * np.r_[-1.0, rng.uniform(0.5, 2.0, p - 1)]) @ Q.T  # indefinite: the least-squares fallback
        S = 0.5 * (S + S.T)
        b = rng.normal(size=p)
        assert np.allclose(kernels.solve_vector(S, b), np.linalg.lstsq(S, b, rcond=None)[0], atol=1e-9)
        assert not kernels.cholesky_solve(S, b.reshape(-1, 1))[1]


@pytest.mark.parametrize(
    "fault",
    ["none", "within_tol", "beyond_tol", "reflection", "nan", "last_row", "shape"],
)
def test_the_compiled_pose_check_decides_as_as_transforms(fault: str) -> None:
    pr = make_problem(8, np.random.default_rng(3))
    T = pr.T_base_flange.copy()
    if fault == "within_tol":
        T[2, :3, :3] *= 1.0 + 0.35 * ORTHONORMAL_TOL  # |R^T R - I| = 0.7 tol: accepted, not by the fast check
    elif fault == "beyond_tol":
        T[2, 0, 1] += 3 * ORTHONORMAL_TOL
    elif fault == "reflection":
        T[4, :3, 0] *= -1.0
    elif fault == "nan":
        T[1, 0, 3] = np.nan
    elif fault == "last_row":
        T[5, 3, 0] = 0.1
    elif fault == "shape":
        T = T[:, :3, :]
    fast = T.shape[1:] == (4, 4) and kernels.rigid_transforms(kernels.c_array(T), 0.5 * ORTHONORMAL_TOL)
    try:
        as_transforms(T, "T_base_flange")
    except ValueError as e:
        assert not fast
        with pytest.raises(ValueError, match=str(e).split(" (")[0].replace("[", r"\[")):
            calibrate(pr.p_cam, T)
        return
    assert fast == (fault == "none")
    cal = calibrate(pr.p_cam, T)
    assert np.isfinite(cal.T_flange_cam).all()


def test_read_only_and_strided_inputs_use_the_compiled_kernels() -> None:
    pr = make_problem(10, np.random.default_rng(4))
    p, T = pr.p_cam.copy(), np.asfortranarray(pr.T_base_flange)
    p.flags.writeable = False
    ref = calibrate(pr.p_cam, pr.T_base_flange)
    assert np.allclose(calibrate(p, T).T_flange_cam, ref.T_flange_cam, rtol=0, atol=1e-12)


def test_warm_kernels_compiles_every_entry_point() -> None:
    warm_kernels()
    entry_points = [
        fk.levenberg_marquardt, fk.linear_system, fk.gauss_newton_steps, influence._influence,
        kernels.inverse, kernels.rigid_transforms, so3.exp_so3, so3.log_so3, so3.project_so3,
        diagnostics.rotation_spread, noise._isotropic_variance,
    ]  # fmt: skip
    assert all(len(f.signatures) == 1 for f in entry_points), [f.py_func.__name__ for f in entry_points]
