"""The frame names SofIA publishes and consumes: one name per frame, the only place they are spelled.

==================  ==============================  =================================================
constant            name                            what it is
==================  ==============================  =================================================
``BASE_FRAME``      ``panda_link0``                 robot base (z up); board, detections, picks
``FLANGE_FRAME``    ``panda_link8``                 flange; parent of the hand-eye calibration
``CAMERA_FRAME``    ``camera_color_optical_frame``  camera optical frame (z forward, x right, y down);
                                                    the clouds' ``frame_id`` and the calibration's child
==================  ==============================  =================================================

The tree: ``panda_link0 -> ... -> panda_link8`` (the robot's /tf), ``panda_link8 ->
camera_color_optical_frame`` (the calibration, ``T_flange_cam``, on /tf_static).

realsense-ros names its body frame ``camera_link`` (x forward, y left, z up) and publishes
``camera_link -> camera_color_optical_frame`` itself. The two differ by the optical rotation
``R_link_optical`` below (plus the colour sensor's small offset, which realsense-ros publishes):
never hang ``camera_link`` under ``panda_link8`` with the calibration's transform.
"""

from __future__ import annotations

import numpy as np

BASE_FRAME = "panda_link0"
FLANGE_FRAME = "panda_link8"
CAMERA_FRAME = "camera_color_optical_frame"
CAMERA_BODY_FRAME = "camera_link"  # realsense-ros's body frame (not published by SofIA)

FRAMES = {"base": BASE_FRAME, "flange": FLANGE_FRAME, "camera": CAMERA_FRAME}

# (3, 3) rotation mapping optical-frame vectors into the body frame (REP 103 / REP 105):
# optical z (forward) = body x, optical x (right) = body -y, optical y (down) = body -z.
# Quaternion x y z w of the same rotation: (-0.5, 0.5, -0.5, 0.5).
R_LINK_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
R_LINK_OPTICAL.flags.writeable = False
