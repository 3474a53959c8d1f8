"""Stage 1, the board: its plane, then its position and yaw in the plane (:func:`fit_board`)."""

from .fit import BoardFit, fit_board

__all__ = ["BoardFit", "fit_board"]
