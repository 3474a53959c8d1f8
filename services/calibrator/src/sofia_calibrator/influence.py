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

from .linalg import inverse
from .solver import Solution

_EYE3_REGULARISED = (1.0 + 1e-12) * np.eye(3)  # I, nudged so that I - H_ii stays invertible


@dataclass
class Influence:
    loo_whitened: np.ndarray  # (m, 3) whitened residual of each sample under the fit without it
    shift: np.ndarray  # (m, p) parameter change when each sample is left out
    p_value: np.ndarray  # (m,) of the studentized deletion F-test (NaN without redundancy)


def influence(sol: Solution) -> Influence:
    """Leave-one-out quantities of a solution over its m samples (see the module docstring)."""
    assert sol.J is not None and sol.whitened is not None
    m, p = len(sol.errors), sol.J.shape[1]
    J = sol.J.reshape(m, 3, p)
    r = sol.whitened
    C = inverse(sol.JtJ)
    JC = J @ C  # (m, 3, p)
    H = JC @ np.swapaxes(J, 1, 2)  # (m, 3, 3) diagonal blocks
    d = np.linalg.solve(_EYE3_REGULARISED - H, r[:, :, None])[:, :, 0]  # (I - H_ii)^-1 r_i
    shift = np.einsum("map,ma->mp", JC, d)
    q = np.einsum("ma,ma->m", r, d)
    dof = 3 * m - p
    rss = float(np.vdot(r, r))
    if dof > 3:
        s2 = np.maximum(rss - q, 1e-300) / (dof - 3)
        pv = fdtrc(3, dof - 3, np.maximum(q, 0.0) / (3 * s2))
    else:
        pv = np.full(m, np.nan)
    return Influence(d, shift, np.asarray(pv))
