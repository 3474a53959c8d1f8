"""Compiled building blocks (numba): small dense symmetric solves and the check of the poses.

A calibration solves systems of 9-15 unknowns over tens of samples, where each numpy call costs more
than its arithmetic; these loops run without LAPACK (quick to compile), for C-contiguous writeable
float64 arrays (:func:`c_array`), cached (``cache=True``) and compiled ahead of the first calibration
by :func:`sofia_calibrator.fitting.warm.warm_kernels` (``scripts/install.sh``, the image).
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
def sym_eig(A):  # type: ignore[no-untyped-def]
    """Eigenvalues (p,) and eigenvectors (p, p), as columns, of a symmetric (p, p) A: cyclic
    Jacobi rotations until the off-diagonal part is below rounding (no LAPACK: fast to compile)."""
    p = A.shape[0]
    a, V = A.copy(), np.eye(p)
    scale = (a * a).sum()
    for _ in range(60):
        off = 0.0
        for i in range(p):
            for j in range(i + 1, p):
                off += a[i, j] * a[i, j]
        if off <= (1e-3 * EPS) ** 2 * scale:
            break
        for i in range(p - 1):
            for j in range(i + 1, p):
                if a[i, j] == 0.0:
                    continue
                theta = (a[j, j] - a[i, i]) / (2.0 * a[i, j])
                t = 0.5 / theta if abs(theta) > 1e150 else 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                t = t if theta >= 0 or abs(theta) > 1e150 else -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                sn = t * c
                for k in range(p):  # A <- A G, then G^T A, V <- V G
                    aki, akj = a[k, i], a[k, j]
                    a[k, i], a[k, j] = c * aki - sn * akj, sn * aki + c * akj
                for k in range(p):
                    aik, ajk = a[i, k], a[j, k]
                    a[i, k], a[j, k] = c * aik - sn * ajk, sn * aik + c * ajk
                for k in range(p):
                    vki, vkj = V[k, i], V[k, j]
                    V[k, i], V[k, j] = c * vki - sn * vkj, sn * vki + c * vkj
    return np.diag(a).copy(), V


@jit
def pinv_solve(A, B, rcond):  # type: ignore[no-untyped-def]
    """X = pinv(A) B for a symmetric (p, p) A, eigenvalues below ``rcond`` times the largest (in
    magnitude) dropped: numpy's ``pinv`` (rcond 1e-15) and ``lstsq`` (rcond eps p) for such an A."""
    ev, V = sym_eig(A)
    p, k = B.shape
    top = np.abs(ev).max()
    X = np.zeros((p, k))
    for i in range(p):
        if abs(ev[i]) <= rcond * top:
            continue
        for c in range(k):
            proj = 0.0
            for m in range(p):
                proj += V[m, i] * B[m, c]
            proj /= ev[i]
            for m in range(p):
                X[m, c] += V[m, i] * proj
    return X


@jit
def inverse(A):  # type: ignore[no-untyped-def]
    """Inverse of a symmetric (p, p) information matrix; the pseudo-inverse when it is singular."""
    X, ok = cholesky_solve(A, np.eye(A.shape[0]))
    return X if ok else pinv_solve(A, np.eye(A.shape[0]), 1e-15)


@jit
def solve_vector(A, b):  # type: ignore[no-untyped-def]
    """x with A x = b, (p, p) symmetric A: Cholesky, least squares when A is not positive definite."""
    p = b.shape[0]
    B = b.copy().reshape((p, 1))
    X, ok = cholesky_solve(A, B)
    if not ok:
        X = pinv_solve(A, B, EPS * p)
    return X.reshape(p)


@jit
def matmul3(A, B):  # type: ignore[no-untyped-def]
    """A B of (3, 3) matrices."""
    C = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            C[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]
    return C


@jit
def solve3(A, b):  # type: ignore[no-untyped-def]
    """x (3,) with A x = b for a (3, 3) A: LU with partial pivoting (LAPACK ``dgesv``'s order)."""
    M, x = A.copy(), b.copy()
    for c in range(3):
        p = c
        for i in range(c + 1, 3):
            if abs(M[i, c]) > abs(M[p, c]):
                p = i
        if p != c:
            for j in range(3):
                M[c, j], M[p, j] = M[p, j], M[c, j]
            x[c], x[p] = x[p], x[c]
        for i in range(c + 1, 3):
            f = M[i, c] / M[c, c]
            for j in range(c + 1, 3):
                M[i, j] -= f * M[c, j]
            x[i] -= f * x[c]
    for i in range(2, -1, -1):
        s = x[i]
        for j in range(i + 1, 3):
            s -= M[i, j] * x[j]
        x[i] = s / M[i, i]
    return x


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
