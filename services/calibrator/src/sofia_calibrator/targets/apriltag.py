"""AprilTag target through OpenCV's ``aruco`` module: each view's T_cam_tag by ``cv2.solvePnP``
(``SOLVEPNP_IPPE``) on the tag's four corners (``cv2.aruco.ArucoDetector``, AprilTag dictionary and
corner refinement), for the pose-target solver as a board's pose; and rendered views for tests.
The tag's frame: origin at its centre, x right, y down (a tag seen face on), z into the tag.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CalibrationError, InputMismatch

RENDER_PX_PER_M = 5000.0  # tag image resolution of :func:`render_tag_view`
QUIET_ZONE = 0.25  # white border around the rendered tag, in tag sides


class TagNotFound(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, view: int, reason: str) -> None:
        super().__init__(f"view {view}: {reason}")


@dataclass(frozen=True)
class TagSpec:
    """One AprilTag: its family (an OpenCV dictionary), id and side (black square, metres)."""

    family: str = "DICT_APRILTAG_36h11"
    tag_id: int = 0
    side_m: float = 0.08

    def dictionary(self):  # type: ignore[no-untyped-def]
        import cv2

        if not self.family.startswith("DICT_APRILTAG") or not hasattr(cv2.aruco, self.family):
            raise InputMismatch(
                f"tag family {self.family!r} is not one of OpenCV's DICT_APRILTAG_* dictionaries"
            )
        if self.side_m <= 0:
            raise InputMismatch(f"tag side must be positive (metres), got {self.side_m}")
        return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.family))

    def corners_tag(self) -> np.ndarray:
        """(4, 3) the tag's corners in its frame (top-left, top-right, bottom-right, bottom-left:
        OpenCV's order of the detected corners), metres."""
        h = self.side_m / 2
        return np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])


def tag_poses(images: list[np.ndarray], K: np.ndarray, spec: TagSpec = TagSpec()) -> np.ndarray:
    """(n, 4, 4) T_cam_tag of n grey images (h, w) uint8 with camera matrix K (3, 3) (rectified).
    Raises :class:`TagNotFound` naming the view without the tag."""
    import cv2

    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3):
        raise InputMismatch(f"K must be the (3, 3) camera matrix, got {K.shape}")
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
    detector = cv2.aruco.ArucoDetector(spec.dictionary(), params)
    out = np.tile(np.eye(4), (len(images), 1, 1))
    for i, img in enumerate(images):
        corners, ids, _ = detector.detectMarkers(img)
        found = [] if ids is None else ids.ravel().tolist()
        if spec.tag_id not in found:
            raise TagNotFound(i, f"tag {spec.tag_id} of {spec.family} not found (found {found})")
        uv = corners[found.index(spec.tag_id)].reshape(4, 2).astype(np.float64)
        ok, rvec, tvec = cv2.solvePnP(spec.corners_tag(), uv, K, None, flags=cv2.SOLVEPNP_IPPE)
        if not ok:
            raise TagNotFound(i, "solvePnP found no pose for the tag's corners")
        out[i, :3, :3] = cv2.Rodrigues(rvec)[0]
        out[i, :3, 3] = tvec.ravel()
    return out


def render_tag_view(
    T_cam_tag: np.ndarray, K: np.ndarray, size: tuple[int, int], spec: TagSpec = TagSpec()
) -> np.ndarray:
    """(h, w) uint8 image of the tag (with a white quiet zone) at T_cam_tag (4, 4) through a
    pinhole K (3, 3), white background; size: (w, h) pixels."""
    import cv2

    s = RENDER_PX_PER_M
    n = round(spec.side_m * s)
    tag = cv2.aruco.generateImageMarker(spec.dictionary(), spec.tag_id, n)
    m = round(QUIET_ZONE * n)
    flat = cv2.copyMakeBorder(tag, m, m, m, m, cv2.BORDER_CONSTANT, value=255)
    # flat pixel (u, v) -> tag frame metres: x = (u + 0.5 - m) / s - side / 2, y likewise
    S = np.array(
        [[1 / s, 0, (0.5 - m) / s - spec.side_m / 2], [0, 1 / s, (0.5 - m) / s - spec.side_m / 2], [0, 0, 1]]
    )
    H = np.asarray(K) @ np.c_[T_cam_tag[:3, :2], T_cam_tag[:3, 3]] @ S
    return np.asarray(cv2.warpPerspective(flat, H, size, flags=cv2.INTER_LINEAR, borderValue=255))
