"""Moving and looking for the autonomous calibration: go to a flange pose, take the next frame
at rest, the camera's rotation from the table seen from flange tilts, and the blob found around.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation
from sofia_calibrator.blob import find_blob
from sofia_calibrator.errors import CalibrationError
from sofia_calibrator.targets.ball import Ball, find_ball
from sofia_calibrator.targets.sphere_shared import fit_shared
from sofia_schemas.transforms import apply, invert, make_transform, pose_gap

from . import plan
from .autocal_io import Eye, Frame, Progress
from .autocal_options import AutocalOptions
from .errors import ArmError
from .motion import ArmMotion
from .poses import Reach, look_at, solve_ik

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
    """The arm and the camera of a calibration run, and what is known of the camera and the target
    (the blob on the table; :class:`BallLooker`: a ball)."""

    TARGET = "blob"  # what the views show, as the progress lines name it

    def __init__(
        self, arm: ArmMotion, eye: Eye, opts: AutocalOptions, progress: Progress, reach: Reach
    ) -> None:
        self.arm, self.eye, self.opts, self.progress, self.reach = arm, eye, opts, progress, reach
        g = opts.guess
        self.T_fc = None if g is None else make_transform(np.array(g[:3]), np.array(g[3:]))
        self.p_base = None if opts.blob is None else np.array(opts.blob, dtype=np.float64)
        self.sightings: list[tuple[np.ndarray, np.ndarray]] = []  # (T_base_flange, p_cam) while orienting
        self.table_z: list[float] = []  # rough table heights (base frame, m) seen while orienting
        self.visited_q: list[np.ndarray] = []  # (7,) joints reached by each move, in order

    def _go(self, T_base_flange: np.ndarray, step: str) -> bool:
        q_now = self.arm.q()
        ik = solve_ik(T_base_flange, q_now, self.reach)
        if not ik.ok:
            log.info("%s: skipped, %s", step, ik.reason)
            return False
        if not self.reach.path_clear(q_now, ik.q):
            log.info(
                "%s: skipped, the tool would pass below %.4f m on the way", step, self.reach.tool_lowest_z
            )
            return False
        res = self.arm.move_joints(ik.q, self.opts.speed)
        if not res.ok and res.status != "failed":  # stopped, preempted, timed out: give up
            raise AutocalError(step, f"move {res.status}: {res.reason}")
        if not self.arm.wait_still(10.0):
            raise AutocalError(step, "the arm did not come to rest (stopped, preempted or timed out)")
        if not res.ok:  # refused, or ended off the target: near enough will do (the pose is measured)
            dt, dr = pose_gap(self.arm.T_base_flange(), T_base_flange)
            if dt > NEAR_M or dr > np.radians(NEAR_DEG):
                log.info("%s: skipped, move failed: %s", step, res.reason)
                return False
        self.visited_q.append(self.arm.q())
        return True

    def go_back(self, q_start: np.ndarray) -> None:
        """Back to the joints ``q_start`` (7,). Where the joint path from here would take the tool
        below the surface, back along the joints visited, shortcut to the earliest whose path is
        clear (each step was clear on the way out, so a way back always exists)."""
        way = [np.asarray(q_start, dtype=np.float64), *self.visited_q]
        while way:
            q_now = self.arm.q()
            i = next((k for k, q in enumerate(way) if self.reach.path_clear(q_now, q)), len(way) - 1)
            res = self.arm.move_joints(way[i], self.opts.speed)
            if not res.ok:
                log.warning("back to the start: stopped on the way (%s)", res.reason)
                return
            del way[i:]

    def _look(self, step: str) -> tuple[np.ndarray, Frame]:
        """(T_base_flange, frame): the next frame stamped after the arm came to rest, taken again
        (up to 3 times) when the flange moved meanwhile (a settling correction)."""
        for _ in range(3):
            T0 = self.arm.T_base_flange()
            frame = self.eye.frame_after(self.arm.stamp_ns(), self.opts.frame_timeout_s)
            if frame is None:
                raise AutocalError(step, f"no camera frame within {self.opts.frame_timeout_s} s")
            T1 = self.arm.T_base_flange()
            dt, dr = pose_gap(T0, T1)
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
            self.sightings.append((T_bf, self.observe(frame)[0]))
        except CalibrationError:
            pass
        return T_bf, frame, plane

    def observe(self, frame: Frame) -> tuple[np.ndarray, float, str]:
        """(p_cam (3,) camera frame m, confidence, description) of the target in a frame; raises
        CalibrationError when it is not seen."""
        assert frame.rgb is not None
        blob = find_blob(frame.points_cam, frame.rgb)
        u, v = blob.centroid_px
        return blob.p_cam, blob.confidence, (f"blob at ({u:.0f}, {v:.0f}) px, {blob.p_cam[2]:.3f} m, "
                                             f"confidence {blob.confidence:.2f}")  # fmt: skip

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
        """The target: seen while orienting, else searched for looking down at the table around."""
        assert self.T_fc is not None
        x0, y0 = self.arm.T_base_flange()[:2, 3]
        if not self.sightings and not self.table_z:
            self._see(f"find {self.TARGET}")
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
            raise AutocalError(f"find {self.TARGET}", f"the {self.TARGET} was not seen around the start pose: "
                               "give its position")  # fmt: skip
        T_bf, p_cam = self.sightings[-1]
        self.p_base = apply(T_bf @ self.T_fc, p_cam)
        self.progress.add(f"find {self.TARGET}", "done",
                          f"{self.TARGET} near {np.round(self.p_base, 3).tolist()} m (base)")  # fmt: skip


class BallLooker(Looker):
    """A coloured ball is the target (:func:`sofia_calibrator.targets.ball.find_ball`): on the
    table eye-in-hand, on the flange eye-to-hand. Its radius is ``opts.ball_radius``, or one
    radius fitted to all the samples' views (:meth:`refit`): a radius fitted in each view alone
    reads small far from the camera and drags that view's centre along the ray."""

    TARGET = "ball"

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.last_seen: tuple[int, Ball] | None = None  # (stamp_ns, ball) of the last frame observed
        self.segments: list[tuple[np.ndarray, np.ndarray, float]] = []  # the samples' views of the ball
        self.seen: list[tuple[int, float]] = []  # (stamp_ns, confidence) of each sample

    def observe(self, frame: Frame) -> tuple[np.ndarray, float, str]:
        assert frame.rgb is not None
        ball = find_ball(frame.points_cam, frame.rgb, self.opts.ball_radius)
        self.last_seen = (frame.stamp_ns, ball)
        u, v = ball.centroid_px
        s = ball.sphere
        return ball.p_cam, ball.confidence, (f"ball at ({u:.0f}, {v:.0f}) px, {s.p_cam[2]:.3f} m, radius "
                                             f"{1e3 * s.radius_m:.1f} mm, confidence {ball.confidence:.2f}")  # fmt: skip

    def refit(self, samples_p: list[np.ndarray]) -> float | None:
        """With the radius unknown, refit the centres of the samples' views (their segments, in
        the order of samples_p) with one radius shared by all of them, writing them into
        samples_p; the shared radius (m), or None while there are fewer than 2 views."""
        if self.opts.ball_radius is not None or len(self.segments) < 2:
            return None
        spheres = fit_shared(self.segments)
        samples_p[:] = [s.p_cam for s in spheres]
        return spheres[0].radius_m
