"""An in-process cell for planning studies and benchmarks: a kinematic Panda that is where it is
told at once, and the blob sheet rendered by the project's simulated D435 (``sofia_replay.synth``,
needed only here) through a true ``T_flange_cam``.

The real loop runs against franky-sim and the camera service's ``--sim`` over Zenoh; this cell
isolates the planning (which poses, how many) from motion and transport.
"""

from __future__ import annotations

import numpy as np
from sofia_schemas.kinematics import panda_fk
from sofia_schemas.messages import ArmResult

from .autocal_io import Frame
from .poses import Q_HOME, Reach


class KinematicArm:
    """An :class:`~sofia_arm.motion.ArmMotion` whose moves take no time; refuses joints outside
    ``reach`` and, as the service does, a joint path taking ``reach``'s tool below its surface.
    ``clock_ns`` advances 1 s per move (the stamp of the state after it)."""

    def __init__(self, q: np.ndarray = Q_HOME, reach: Reach | None = None) -> None:
        self._q = np.array(q, dtype=np.float64)
        self.reach = reach or Reach()
        self.clock_ns = 1_700_000_000_000_000_000
        self.moves = 0

    def _result(self, ok: bool, reason: str = "") -> ArmResult:
        return ArmResult(ok=ok, command="move_joints", status="done" if ok else "failed", reason=reason,
                         q=tuple(self._q))  # fmt: skip

    def move_joints(self, q_rad: np.ndarray, speed: float) -> ArmResult:
        q = np.asarray(q_rad, dtype=np.float64)
        if np.any(q < self.reach.q_lo - 1e-9) or np.any(q > self.reach.q_hi + 1e-9):
            return self._result(False, f"joints {np.round(q, 3).tolist()} outside the margins")
        if not self.reach.in_box(panda_fk(q, check_limits=False)[:3, 3])[0]:
            return self._result(False, "flange outside the workspace box")
        if not self.reach.path_clear(self._q, q):
            return self._result(False, "the tool would pass below the surface on the way")
        self._q = q
        self.moves += 1
        self.clock_ns += 1_000_000_000
        return self._result(True)

    def move_pose(self, T_base_flange: np.ndarray, speed: float) -> ArmResult:
        from .poses import solve_ik

        ik = solve_ik(T_base_flange, self._q, self.reach)
        return self.move_joints(ik.q, speed) if ik.ok else self._result(False, ik.reason)

    def T_base_flange(self) -> np.ndarray:
        return np.asarray(panda_fk(self._q, check_limits=False))

    def q(self) -> np.ndarray:
        return self._q.copy()

    def wait_still(self, timeout_s: float) -> bool:
        return True

    def stamp_ns(self) -> int:
        return self.clock_ns


class SheetEye:
    """The blob sheet (``sofia_replay.synth.CalibrationTarget``) seen by a D435 on the flange of
    ``arm`` at the true ``T_flange_cam`` (4, 4)."""

    def __init__(
        self, arm: KinematicArm, T_flange_cam: np.ndarray, p_blob_base: np.ndarray, seed: int = 0
    ) -> None:
        from sofia_replay.synth import CalibrationTarget, Camera

        self.arm, self.T_flange_cam = arm, np.asarray(T_flange_cam, dtype=np.float64)
        self.target = CalibrationTarget(p_base=np.asarray(p_blob_base, dtype=np.float64))
        self.camera = Camera()
        self.scene = self.target.build()
        self.rng = np.random.default_rng(seed)
        self.frames = 0

    def frame_after(self, stamp_ns: int, timeout_s: float) -> Frame | None:
        from sofia_replay.synth.camera import render

        T_base_cam = self.arm.T_base_flange() @ self.T_flange_cam
        r = render(self.scene[0], self.scene[1], T_base_cam, self.camera, self.rng)
        self.frames += 1
        return Frame(max(stamp_ns, self.arm.clock_ns), r.points_cam.astype(np.float64), r.rgb)


class BallEye:
    """A fixed D435 at ``T_base_cam`` (4, 4) seeing the ball on the flange of ``arm`` (the camera
    service's eye-to-hand cell, ``sofia_camera.sim_fixed``, needed only here)."""

    def __init__(
        self, arm: KinematicArm, T_base_cam: np.ndarray, p_flange: tuple[float, float, float],
        radius_m: float, seed: int = 0,
    ) -> None:  # fmt: skip
        from sofia_camera.sim_fixed import FixedCameraCell, eye_to_hand_state
        from sofia_replay.synth import Camera

        self.arm = arm
        self.cell = FixedCameraCell(eye_to_hand_state(T_base_cam, p_flange, radius_m))
        self.camera = Camera()
        self.rng = np.random.default_rng(seed)
        self.frames = 0

    def frame_after(self, stamp_ns: int, timeout_s: float) -> Frame | None:
        from sofia_replay.synth.camera import render

        rc, colour_of = self.cell.scene_at(self.arm.T_base_flange())
        r = render(rc, colour_of, self.cell.T_base_cam, self.camera, self.rng)
        self.frames += 1
        return Frame(max(stamp_ns, self.arm.clock_ns), r.points_cam.astype(np.float64), r.rgb)


class TableBallEye(SheetEye):
    """A D435 on the flange of ``arm`` at the true ``T_flange_cam`` (4, 4) seeing a coloured ball
    of ``radius_m`` lying on the table at ``p_ball_base`` (3,), base frame, metres."""

    def __init__(
        self,
        arm: KinematicArm,
        T_flange_cam: np.ndarray,
        p_ball_base: np.ndarray,
        radius_m: float,
        seed: int = 0,
    ) -> None:
        from sofia_camera.sim_fixed import table_and_ball
        from sofia_replay.synth import Camera

        self.arm, self.T_flange_cam = arm, np.asarray(T_flange_cam, dtype=np.float64)
        self.scene = table_and_ball(np.asarray(p_ball_base, dtype=np.float64), radius_m)
        self.camera = Camera()
        self.rng = np.random.default_rng(seed)
        self.frames = 0
