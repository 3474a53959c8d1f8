"""The numba compiler as the detector uses it, and the small solve its compiled fits share.

Kernels are compiled for C-contiguous arrays, cached beside the sources (``cache=True``;
``~/.cache/numba`` when that is read-only) and compiled ahead of the first detection
(:func:`sofia_detector.warmup.compile_kernels`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@jit
def solve_spd(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x of ``A x = b`` for an (n, n) symmetric positive definite A (Cholesky); NaN when it is not."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for m in range(j):
                s -= L[i, m] * L[j, m]
            if i == j:
                if s <= 0.0:
                    return np.full(n, np.nan)
                L[i, i] = math.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    y = np.empty(n)
    for i in range(n):
        s = b[i]
        for m in range(i):
            s -= L[i, m] * y[m]
        y[i] = s / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for m in range(i + 1, n):
            s -= L[m, i] * x[m]
        x[i] = s / L[i, i]
    return x
