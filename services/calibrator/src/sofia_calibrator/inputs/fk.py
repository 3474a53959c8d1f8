"""Franka Emika Panda forward kinematics: the project's one implementation lives in
:mod:`sofia_schemas.kinematics` (shared with the arm service); here its errors are the calibrator's."""

from __future__ import annotations

import numpy as np
from sofia_schemas.kinematics import PANDA_DH, Q_MAX, Q_MIN, KinematicsError
from sofia_schemas.kinematics import panda_fk as _panda_fk

from ..errors import InputMismatch

__all__ = ["PANDA_DH", "Q_MAX", "Q_MIN", "panda_fk"]


def panda_fk(q: np.ndarray, check_limits: bool = True) -> np.ndarray:
    """T_base_flange (n, 4, 4) of joint positions q (n, 7) or (7,) radians (base = panda_link0).

    Raises InputMismatch for a wrong shape, non-finite values or (``check_limits``) a joint
    outside Franka's limits.
    """
    try:
        return _panda_fk(q, check_limits)
    except KinematicsError as e:
        raise InputMismatch(str(e)) from None
