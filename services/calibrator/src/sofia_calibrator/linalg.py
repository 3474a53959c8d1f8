"""Small dense symmetric solves through LAPACK directly.

The solver works on 9-11 unknowns, where numpy.linalg's per-call checks cost more than the
factorisation itself; ``dposv`` (Cholesky factor and solve in one call) does not.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.linalg.lapack import dposv


@lru_cache(maxsize=16)
def _eye(p: int) -> np.ndarray:
    eye = np.eye(p)
    eye.flags.writeable = False
    return eye


def spd_solve(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """x with A x = b for a symmetric positive-definite (p, p) A and (p,) or (p, k) b; None when A
    is not positive definite (the caller decides the fallback)."""
    _, x, info = dposv(A, b)
    return np.asarray(x) if info == 0 else None


def inverse(A: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric (p, p) information matrix; the pseudo-inverse when it is singular."""
    x = spd_solve(A, _eye(A.shape[0]))
    return x if x is not None else np.asarray(np.linalg.pinv(A))
