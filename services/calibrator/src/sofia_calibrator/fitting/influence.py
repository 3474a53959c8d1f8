"""Leave-one-out from one fit: the hat matrix of the whitened Jacobian instead of n refits.

For a least-squares fit with whitened Jacobian J (3 m x p) and whitened residuals r (m x 3), the
3 x 3 diagonal blocks of H = J (J^T J)^-1 J^T give, to first order (one Gauss-Newton step, exact
for a linear model):

- the residual of sample i under the fit without it: d_i = (I - H_ii)^-1 r_i;
- the parameter change when it is left out: dx_i = C J_i^T (I - H_ii)^-1 r_i, C = (J^T J)^-1;
- the externally studentized statistic F_i = r_i^T (I - H_ii)^-1 r_i / (3 s_(i)^2), distributed
  as F(3, dof - 3) for a good sample, s_(i)^2 the noise estimated without it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import fdtrc

from .kernels import inverse, jit
from .solver import Solution


@dataclass
class Influence:
    loo_whitened: np.ndarray  # (m, 3) whitened residual of each sample under the fit without it
    shift: np.ndarray  # (m, p) parameter change when each sample is left out
    p_value: np.ndarray  # (m,) of the studentized deletion F-test (NaN without redundancy)


def influence(sol: Solution) -> Influence:
    """Leave-one-out quantities of a solution over its m samples (see the module docstring)."""
    assert sol.J is not None and sol.whitened is not None
    r = sol.whitened
    d, shift, q = _influence(sol.J, r, sol.JtJ)
    dof = 3 * len(r) - sol.J.shape[1]
    if dof > 3:
        s2 = np.maximum(float(np.vdot(r, r)) - q, 1e-300) / (dof - 3)
        pv = fdtrc(3, dof - 3, np.maximum(q, 0.0) / (3 * s2))
    else:
        pv = np.full(len(r), np.nan)
    return Influence(d, shift, np.asarray(pv))


@jit
def _influence(J, r, JtJ):  # type: ignore[no-untyped-def]
    """Leave-one-out quantities of a fit (see the module docstring): whitened Jacobian
    J (3 m, p), whitened residuals r (m, 3), information JtJ (p, p). Returns (d (m, 3): (I - H_ii)^-1
    r_i, shift (m, p): C J_i^T d_i, q (m,): r_i . d_i)."""
    m, p = r.shape[0], J.shape[1]
    JC = J @ inverse(JtJ)
    d, shift, q = np.empty((m, 3)), np.empty((m, p)), np.empty(m)
    I_nudged = np.eye(3) * (1.0 + 1e-12)  # so that I - H_ii stays invertible
    for i in range(m):
        rows = slice(3 * i, 3 * i + 3)
        d[i] = np.linalg.solve(I_nudged - JC[rows] @ J[rows].T, r[i])
        q[i] = r[i] @ d[i]
        shift[i] = d[i] @ JC[rows]
    return d, shift, q
