"""Compiled building blocks (numba): small dense symmetric solves and the check of the poses.

A calibration solves systems of 9-15 unknowns over tens of samples, where each numpy call from
Python costs more than its arithmetic. The kernels take C-contiguous writeable float64 arrays
(:func:`c_array`), are cached (``cache=True``) and compiled ahead of the first calibration by
:func:`sofia_calibrator.fitting.warm.warm_kernels` (``scripts/install.sh``, the image).
"""

from __future__ import annotations

import math

import numba
import numpy as np

EPS = float(np.finfo(np.float64).eps)
jit = numba.njit(cache=True, nogil=True, error_model="numpy")


def c_array(a: np.ndarray) -> np.ndarray:
    """``a`` as the kernels are compiled for: C-contiguous, writeable float64 (copied when not)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    return a if a.flags.writeable else a.copy()


@jit
def cholesky_solve(A, B):  # type: ignore[no-untyped-def]
    """(X (p, k), ok) with A X = B for a symmetric positive-definite (p, p) A (its lower triangle is
    read); ok False (X undefined) when A is not positive definite, as LAPACK ``dposv`` reports."""
    p, k = B.shape
    L = np.zeros((p, p))
    for j in range(p):
        s = A[j, j]
        for m in range(j):
            s -= L[j, m] * L[j, m]
        if not s > 0.0:  # also NaN
            return B.copy(), False
        d = math.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, p):
            s = A[i, j]
            for m in range(j):
                s -= L[i, m] * L[j, m]
            L[i, j] = s / d
    X = B.copy()
    for c in range(k):
        for i in range(p):  # L y = b
            s = X[i, c]
            for m in range(i):
                s -= L[i, m] * X[m, c]
            X[i, c] = s / L[i, i]
        for i in range(p - 1, -1, -1):  # L^T x = y
            s = X[i, c]
            for m in range(i + 1, p):
                s -= L[m, i] * X[m, c]
            X[i, c] = s / L[i, i]
    return X, True


@jit
def inverse(A):  # type: ignore[no-untyped-def]
    """Inverse of a symmetric (p, p) information matrix; the pseudo-inverse when it is singular."""
    X, ok = cholesky_solve(A, np.eye(A.shape[0]))
    return X if ok else np.ascontiguousarray(np.linalg.pinv(A, 1e-15))


@jit
def solve_vector(A, b):  # type: ignore[no-untyped-def]
    """x with A x = b, (p, p) symmetric A: Cholesky, least squares (numpy's ``lstsq`` cut-off) when A
    is not positive definite."""
    p = b.shape[0]
    X, ok = cholesky_solve(A, b.copy().reshape((p, 1)))
    return X.reshape(p) if ok else np.linalg.pinv(A, EPS * p) @ b


@jit
def rigid_transforms(T, tol):  # type: ignore[no-untyped-def]
    """True when every (4, 4) matrix of T (n, 4, 4) is finite, its rotation block orthonormal
    (|R^T R - I| <= tol per entry) with det >= 0 and its last row [0, 0, 0, 1] within tol: the
    conditions of ``sofia_schemas.transforms.as_transforms``, checked without numpy temporaries."""
    for i in range(T.shape[0]):
        for a in range(4):
            for b in range(4):
                if not math.isfinite(T[i, a, b]):
                    return False
            if abs(T[i, 3, a] - (1.0 if a == 3 else 0.0)) > tol:
                return False
        for a in range(3):
            for b in range(3):
                g = T[i, 0, a] * T[i, 0, b] + T[i, 1, a] * T[i, 1, b] + T[i, 2, a] * T[i, 2, b]
                if abs(g - (1.0 if a == b else 0.0)) > tol:
                    return False
        det = (T[i, 0, 0] * (T[i, 1, 1] * T[i, 2, 2] - T[i, 1, 2] * T[i, 2, 1])
               - T[i, 0, 1] * (T[i, 1, 0] * T[i, 2, 2] - T[i, 1, 2] * T[i, 2, 0])
               + T[i, 0, 2] * (T[i, 1, 0] * T[i, 2, 1] - T[i, 1, 1] * T[i, 2, 0]))  # fmt: skip
        if det < 0:
            return False
    return True
