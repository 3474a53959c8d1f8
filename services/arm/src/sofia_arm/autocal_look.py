"""Moving and looking for the autonomous calibration: go to a flange pose, take the next frame
at rest, the camera's rotation from the table seen from flange tilts, and the blob found around.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.spatial.transform import Rotation
from sofia_calibrator.blob import find_blob
from sofia_calibrator.errors import CalibrationError
from sofia_schemas.transforms import apply, invert, make_transform

from . import plan
from .autocal_io import Eye, Frame, Progress
from .autocal_options import AutocalOptions
from .errors import ArmError
from .motion import ArmMotion
from .poses import Reach, look_at, pose_distance, solve_ik

log = logging.getLogger("sofia.arm.autocal")

# flange tilts (about its x, then y axis, degrees) from the start pose while finding the table
ORIENT_TILTS_DEG = ((0, 0), (25, 0), (0, 25), (-25, 0), (0, -25), (50, 0), (0, 50), (-50, 0), (0, -50),
                    (90, 0), (0, 90), (-90, 0), (0, -90), (135, 0), (0, 135), (-135, 0), (0, -135))  # fmt: skip
SEARCH_XY_M = ((0.0, 0.0), (0.2, 0.2), (0.2, -0.2), (-0.1, 0.25), (-0.1, -0.25), (0.35, 0.0))
SEARCH_HEIGHT_M = 0.55  # the camera above the table while searching (a 0.55 x 0.4 m footprint)
NEAR_M, NEAR_DEG = 0.005, 1.0  # a move that ended this close to its view still serves (the pose is measured)
STILL_M, STILL_DEG = 2e-4, 0.02  # the flange moved less than this while a frame was taken


class AutocalError(ArmError):
    """The autonomous calibration could not go on; the message says why."""

    def __init__(self, step: str, reason: str) -> None:
        super().__init__(f"{step}: {reason}")
        self.step, self.reason = step, reason


class Looker:
    """The arm and the camera of a calibration run, and what is known of the camera and the blob."""

    def __init__(
        self, arm: ArmMotion, eye: Eye, opts: AutocalOptions, progress: Progress, reach: Reach
    ) -> None:
        self.arm, self.eye, self.opts, self.progress, self.reach = arm, eye, opts, progress, reach
        g = opts.guess
        self.T_fc = None if g is None else make_transform(np.array(g[:3]), np.array(g[3:]))
        self.p_base = None if opts.blob is None else np.array(opts.blob, dtype=np.float64)
        self.sightings: list[tuple[np.ndarray, np.ndarray]] = []  # (T_base_flange, p_cam) while orienting
        self.table_z: list[float] = []  # rough table heights (base frame, m) seen while orienting

    def _go(self, T_base_flange: np.ndarray, step: str) -> bool:
        ik = solve_ik(T_base_flange, self.arm.q(), self.reach)
        if not ik.ok:
            log.info("%s: skipped, %s", step, ik.reason)
            return False
        res = self.arm.move_joints(ik.q, self.opts.speed)
        if not res.ok and res.status != "failed":  # stopped, preempted, timed out: give up
            raise AutocalError(step, f"move {res.status}: {res.reason}")
        if not self.arm.wait_still(10.0):
            raise AutocalError(step, "the arm did not come to rest (stopped, preempted or timed out)")
        if not res.ok:  # refused, or ended off the target: near enough will do (the pose is measured)
            dt, dr = pose_distance(self.arm.T_base_flange(), T_base_flange)
            if dt > NEAR_M or dr > np.radians(NEAR_DEG):
                log.info("%s: skipped, move failed: %s", step, res.reason)
                return False
        return True

    def _look(self, step: str) -> tuple[np.ndarray, Frame]:
        """(T_base_flange, frame): the next frame stamped after the arm came to rest, taken again
        (up to 3 times) when the flange moved meanwhile (a settling correction)."""
        for _ in range(3):
            T0 = self.arm.T_base_flange()
            frame = self.eye.frame_after(self.arm.stamp_ns(), self.opts.frame_timeout_s)
            if frame is None:
                raise AutocalError(step, f"no camera frame within {self.opts.frame_timeout_s} s")
            T1 = self.arm.T_base_flange()
            dt, dr = pose_distance(T0, T1)
            if dt < STILL_M and dr < np.radians(STILL_DEG):
                return T1, frame
            if not self.arm.wait_still(10.0):
                raise AutocalError(step, "the arm did not come to rest (stopped, preempted or timed out)")
        raise AutocalError(step, f"the flange kept moving while frames were taken ({dt * 1e3:.2f} mm)")

    def _see(self, step: str) -> tuple[np.ndarray, Frame, tuple[np.ndarray, float] | None]:
        """Look, remember a blob seen on the way; (T_base_flange, frame, table plane or None)."""
        T_bf, frame = self._look(step)
        if frame.rgb is None:
            raise AutocalError(step, "the camera frames have no colour")
        plane = plan.table_plane_cam(frame.points_cam)
        if plane is not None:
            self.table_z.append(T_bf[2, 3] - plane[1])  # camera ~ flange height: a rough table height
        try:
            self.sightings.append((T_bf, find_blob(frame.points_cam, frame.rgb).p_cam))
        except CalibrationError:
            pass
        return T_bf, frame, plane

    # --- 1. the camera's rotation from the table ----------------------------------------------
    def orient(self) -> None:
        T_start = self.arm.T_base_flange()
        poses, normals = [], []
        for ax, ay in ORIENT_TILTS_DEG:
            T = T_start.copy()
            T[:3, :3] = T_start[:3, :3] @ Rotation.from_euler("xy", [ax, ay], degrees=True).as_matrix()
            if not self._go(T, f"orient {ax:+d}/{ay:+d} deg"):
                continue
            T_bf, _, plane = self._see("orient")
            if plane is not None:
                poses.append(T_bf)
                normals.append(plane[0])
            up = np.array([T[2, :3] for T in poses])
            if len(poses) >= 3 and np.linalg.svd(up - up.mean(0), compute_uv=False)[1] > 0.1:
                break
        if len(poses) < 2:
            raise AutocalError(
                "orient", f"the table was seen in {len(poses)} view(s), 2 needed: give a guess"
            )
        T_fc = np.eye(4)
        T_fc[:3, :3] = plan.rotation_from_table(np.array(poses), np.array(normals))
        self.T_fc = T_fc
        self.progress.add("orient", "done", f"camera axis in the flange frame {np.round(T_fc[:3, 2], 3).tolist()} "
                          f"from the table in {len(poses)} views")  # fmt: skip

    def find(self) -> None:
        """The blob: seen while orienting, else searched for looking down at the table around."""
        assert self.T_fc is not None
        x0, y0 = self.arm.T_base_flange()[:2, 3]
        if not self.sightings and not self.table_z:
            self._see("find blob")
        for dx, dy in SEARCH_XY_M:
            if self.sightings or not self.table_z:
                break
            target = np.array([x0 + dx, y0 + dy, float(np.median(self.table_z))])
            for roll in (0.0, 90.0, 180.0, 270.0):
                eye = target + np.array([0.0, 0.0, SEARCH_HEIGHT_M])
                if self._go(look_at(eye, target, np.radians(roll)) @ invert(self.T_fc), "search"):
                    self._see("search")
                    break
        if not self.sightings:
            raise AutocalError("find blob", "the blob was not seen around the start pose: give its position")
        T_bf, p_cam = self.sightings[-1]
        self.p_base = apply(T_bf @ self.T_fc, p_cam)
        self.progress.add("find blob", "done", f"blob near {np.round(self.p_base, 3).tolist()} m (base)")
