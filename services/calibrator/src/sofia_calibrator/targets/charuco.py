"""ChArUco board target through OpenCV's ``aruco`` module: each view's board pose T_cam_board by
``cv2.solvePnP`` on its ChArUco corners (``cv2.aruco.CharucoDetector``), for the pose-target solver
(:func:`~.poses.hand_eye_from_poses`; the corners with depth: :mod:`.board_points`), and rendered
views for tests and benchmarks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CalibrationError, InputMismatch

MIN_CORNERS = 6
RENDER_PX_PER_M = 5000.0  # board image resolution of :func:`render_view`


class BoardNotFound(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, view: int, n_corners: int) -> None:
        super().__init__(f"view {view}: {n_corners} ChArUco corners found, at least {MIN_CORNERS} are needed")


@dataclass(frozen=True)
class BoardSpec:
    """A ChArUco board: squares (columns, rows), square and marker sides (metres), dictionary."""

    squares: tuple[int, int] = (7, 5)
    square_m: float = 0.04
    marker_m: float = 0.03
    dictionary: str = "DICT_5X5_100"

    def board(self):  # type: ignore[no-untyped-def]
        import cv2

        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(self.squares, self.square_m, self.marker_m, d)

    @property
    def size_m(self) -> tuple[float, float]:
        return self.squares[0] * self.square_m, self.squares[1] * self.square_m


def board_poses(images: list[np.ndarray], K: np.ndarray, spec: BoardSpec = BoardSpec()) -> np.ndarray:
    """(n, 4, 4) T_cam_board of n grey images (h, w) uint8 with camera matrix K (3, 3) (no lens
    distortion: rectified images). Raises :class:`BoardNotFound` naming the view that fails."""
    import cv2

    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3):
        raise InputMismatch(f"K must be the (3, 3) camera matrix, got {K.shape}")
    board = spec.board()
    detector = cv2.aruco.CharucoDetector(board)
    layout = board.getChessboardCorners()
    out = np.tile(np.eye(4), (len(images), 1, 1))
    for i, img in enumerate(images):
        corners, ids, _, _ = detector.detectBoard(img)
        n = 0 if ids is None else len(ids)
        if n < MIN_CORNERS:
            raise BoardNotFound(i, n)
        ok, rvec, tvec = cv2.solvePnP(layout[ids.ravel()], corners.reshape(-1, 2), K, None,
                                      flags=cv2.SOLVEPNP_ITERATIVE)  # fmt: skip
        if not ok:
            raise BoardNotFound(i, n)
        out[i, :3, :3] = cv2.Rodrigues(rvec)[0]
        out[i, :3, 3] = tvec.ravel()
    return out


def render_view(
    T_cam_board: np.ndarray, K: np.ndarray, size: tuple[int, int], spec: BoardSpec = BoardSpec()
) -> np.ndarray:
    """(h, w) uint8 image of the board at T_cam_board (4, 4) through a pinhole K (3, 3), white
    background; size: (w, h) pixels. The board lies in its z = 0 plane, x and y along its sides."""
    import cv2

    w_m, h_m = spec.size_m
    s = RENDER_PX_PER_M
    flat = spec.board().generateImage((round(w_m * s), round(h_m * s)), marginSize=0)
    S = np.array([[1 / s, 0, 0.5 / s], [0, 1 / s, 0.5 / s], [0, 0, 1]])  # board pixel -> metres
    H = np.asarray(K) @ np.c_[T_cam_board[:3, :2], T_cam_board[:3, 3]] @ S
    return np.asarray(cv2.warpPerspective(flat, H, size, flags=cv2.INTER_LINEAR, borderValue=255))
