"""Reachable flange poses: numerical inverse kinematics on the Panda, the workspace box, and
camera views of a point (the calibration blob) turned into flange poses.

Frames: base = ``panda_link0`` (z up), flange = ``panda_link8``, camera = optical frame (z forward,
x right, y down). ``T_a_b`` maps points of frame b into frame a; metres, radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation
from sofia_schemas.kinematics import RobotModel, joint_limits, panda_fk

from .tool import joint_path

Q_HOME = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
IK_POS_TOL_M = 1e-5
IK_ROT_TOL_RAD = 1e-4
IK_ACCEPT_POS_M = 5e-5  # a solution this close is taken (the arm's own accuracy is ~0.1 mm)
IK_ACCEPT_ROT_RAD = 3e-4
FD_STEP_RAD = 1e-6


@dataclass(frozen=True)
class Reach:
    """What the planner may ask of the arm: the joint limits of ``model`` shrunk by ``joint_margin``
    (rad) and a box (base frame, metres) the flange origin must stay in."""

    joint_margin: float = 0.1
    box_min: tuple[float, float, float] = (0.15, -0.6, 0.05)
    box_max: tuple[float, float, float] = (0.8, 0.6, 0.9)
    # the tool's outline (flange frame, m) and the lowest height (base frame, m) it may reach:
    # the service's rule of the tool above the surface (:mod:`sofia_arm.tool`); none by default
    tool_points_flange: tuple[tuple[float, float, float], ...] = ()
    tool_lowest_z: float = -np.inf
    model: RobotModel = "panda"

    @property
    def q_lo(self) -> np.ndarray:
        return joint_limits(self.model)[0] + self.joint_margin

    @property
    def q_hi(self) -> np.ndarray:
        return joint_limits(self.model)[1] - self.joint_margin

    def in_box(self, p_base: np.ndarray) -> np.ndarray:
        """(n,) bool: flange positions (n, 3) (base frame) inside the box."""
        p = np.atleast_2d(p_base)
        return np.all((p >= np.array(self.box_min)) & (p <= np.array(self.box_max)), axis=-1)

    def tool_clear(self, T_base_flange: np.ndarray) -> np.ndarray:
        """(n,) bool: flange poses (n, 4, 4) or (4, 4) (base frame) whose tool stays at or above
        ``tool_lowest_z``."""
        T = np.asarray(T_base_flange, dtype=np.float64).reshape(-1, 4, 4)
        if not self.tool_points_flange:
            return np.ones(len(T), dtype=bool)
        pts = np.asarray(self.tool_points_flange)
        z = np.einsum("nj,kj->nk", T[:, 2, :3], pts) + T[:, 2, 3:4]  # (n, k) heights of the tool's points
        return np.asarray(z.min(axis=1) >= self.tool_lowest_z)

    def path_clear(self, q_from: np.ndarray, q_to: np.ndarray) -> bool:
        """True when the tool stays at or above ``tool_lowest_z`` all along the joint motion from
        ``q_from`` to ``q_to`` (7,) rad: the arm service's check before a joint move
        (:meth:`sofia_arm.safety.Safety.check_joint_target`), for a planner to skip what it refuses."""
        if not self.tool_points_flange:
            return True
        q0, q1 = (np.asarray(q, dtype=np.float64) for q in (q_from, q_to))
        return bool(self.tool_clear(joint_path(q0, q1)).all())


@dataclass
class IkResult:
    q: np.ndarray  # (7,) joint positions, rad
    position_error_m: float
    rotation_error_rad: float
    ok: bool
    seeds_tried: int = 0
    reason: str = ""
    T_base_flange: np.ndarray = field(default_factory=lambda: np.eye(4))


def pose_error(T_target: np.ndarray, T: np.ndarray) -> np.ndarray:
    """(6,) error of pose T towards T_target, base frame: translation (m), rotation vector (rad)."""
    dR = T_target[:3, :3] @ T[:3, :3].T
    return np.concatenate([T_target[:3, 3] - T[:3, 3], Rotation.from_matrix(dR).as_rotvec()])


def jacobian(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T_base_flange (4, 4), geometric Jacobian (6, 7) in the base frame) by finite differences."""
    qs = np.vstack([q, q + FD_STEP_RAD * np.eye(7)])
    Ts = panda_fk(qs, check_limits=False)
    T0 = Ts[0]
    dp = (Ts[1:, :3, 3] - T0[:3, 3]) / FD_STEP_RAD
    dR = np.einsum("nij,kj->nik", Ts[1:, :3, :3], T0[:3, :3])  # R(q + h e_i) R(q)^T
    dw = Rotation.from_matrix(dR).as_rotvec() / FD_STEP_RAD
    return T0, np.vstack([dp.T, dw.T])


def _solve_from(
    T_target: np.ndarray, q: np.ndarray, reach: Reach, iters: int
) -> tuple[np.ndarray, np.ndarray]:
    """Damped least squares with joint clamping and a null-space pull to mid-range."""
    lo, hi = reach.q_lo, reach.q_hi
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    e = np.full(6, np.inf)
    for _ in range(iters):
        T, J = jacobian(q)
        e = pose_error(T_target, T)
        if np.linalg.norm(e[:3]) < IK_POS_TOL_M and np.linalg.norm(e[3:]) < IK_ROT_TOL_RAD:
            break
        lam2 = 1e-6 + 1e-2 * float(e @ e)
        J_pinv = J.T @ np.linalg.inv(J @ J.T + lam2 * np.eye(6))
        step = J_pinv @ np.clip(e, -0.2, 0.2)
        if float(e @ e) > 1e-6:  # pull towards mid-range only while far from the target
            step += (np.eye(7) - J_pinv @ J) @ (0.1 * (mid - q) / half**2)
        q = np.clip(q + step, lo, hi)
    return q, e


def solve_ik(
    T_base_flange: np.ndarray,
    q_seed: np.ndarray | None = None,
    reach: Reach | None = None,
    n_random_seeds: int = 6,
    iters: int = 100,
    rng: np.random.Generator | None = None,
) -> IkResult:
    """Joint positions (within ``reach``'s limits) placing the flange at ``T_base_flange`` (4, 4).

    Tries ``q_seed`` (e.g. the arm's current joints), the home pose, then random seeds; returns the
    first solution within 0.05 mm / 0.02 deg, else the best one with ``ok=False`` and the reason.
    The flange position must lie inside the workspace box, the tool (when ``reach`` has one)
    above its lowest height.
    """
    reach = reach or Reach()
    T_target = np.asarray(T_base_flange, dtype=np.float64)
    if not reach.in_box(T_target[:3, 3])[0]:
        return IkResult(Q_HOME.copy(), np.inf, np.inf, False, 0,
                        f"flange position {np.round(T_target[:3, 3], 3).tolist()} m is outside the workspace box "
                        f"{list(reach.box_min)}..{list(reach.box_max)}")  # fmt: skip
    if not reach.tool_clear(T_target)[0]:
        return IkResult(Q_HOME.copy(), np.inf, np.inf, False, 0,
                        f"the tool at flange position {np.round(T_target[:3, 3], 3).tolist()} m would come "
                        f"below z = {reach.tool_lowest_z:.4f} m (the surface plus its margin)")  # fmt: skip
    rng = rng or np.random.default_rng(0)
    seeds = [np.clip(s, reach.q_lo, reach.q_hi) for s in ([] if q_seed is None else [np.asarray(q_seed)])]
    seeds.append(np.clip(Q_HOME, reach.q_lo, reach.q_hi))
    seeds += list(rng.uniform(reach.q_lo, reach.q_hi, (n_random_seeds, 7)))
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    for k, seed in enumerate(seeds, start=1):
        q, e = _solve_from(T_target, seed.astype(np.float64), reach, iters)
        ep, er = float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))
        if ep < IK_ACCEPT_POS_M and er < IK_ACCEPT_ROT_RAD:
            return IkResult(q, ep, er, True, k, "", panda_fk(q, check_limits=False))
        score = ep + 0.1 * er
        if best is None or score < best[0]:
            best = (score, q, e)
    assert best is not None
    _, q, e = best
    ep, er = float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))
    return IkResult(q, ep, er, False, len(seeds),
                    f"no joint solution within the limits (margin {reach.joint_margin} rad): best is "
                    f"{ep * 1e3:.1f} mm / {np.degrees(er):.2f} deg off", panda_fk(q, check_limits=False))  # fmt: skip


def look_at(eye_base: np.ndarray, target_base: np.ndarray, roll: float | np.ndarray) -> np.ndarray:
    """``T_base_cam`` (4, 4), or (n, 4, 4) for eyes (n, 3) and rolls (n,), of optical frames at
    ``eye`` looking at ``target`` (3,) (base frame, metres).

    ``roll`` (rad) turns the image about the optical axis: 0 puts the image x axis as close as
    possible to the base y axis (or the base x axis when looking along y).
    """
    eyes = np.atleast_2d(np.asarray(eye_base, dtype=np.float64))
    rolls = np.broadcast_to(np.asarray(roll, dtype=np.float64), (len(eyes),))
    z = np.asarray(target_base, float) - eyes
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    hint = np.where(np.abs(z[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    x = hint - np.sum(hint * z, axis=1, keepdims=True) * z
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    R_look = np.stack([x, np.cross(z, x), z], axis=2)
    R_roll = Rotation.from_rotvec(np.c_[np.zeros((len(eyes), 2)), rolls]).as_matrix()
    T = np.tile(np.eye(4), (len(eyes), 1, 1))
    T[:, :3, :3], T[:, :3, 3] = R_look @ R_roll, eyes
    return T if np.ndim(eye_base) > 1 else T[0]


def views_of(
    target_base: np.ndarray,
    tilts_deg: np.ndarray,
    azimuths_deg: np.ndarray,
    distances_m: np.ndarray,
    rolls_deg: np.ndarray,
    offsets_deg: np.ndarray | None = None,
) -> np.ndarray:
    """(n, 4, 4) ``T_base_cam`` viewing ``target_base`` (3,) from every combination of tilt from
    the vertical, azimuth about the base z axis, distance, roll about the optical axis and image
    offset: ``offsets_deg`` (k, 2) turns the camera so that the target appears that far (degrees)
    right and down of the image centre (default: centred only). A target on the optical axis
    leaves the rotation about that axis unobserved, so calibration views need offsets.
    """
    offsets = np.zeros((1, 2)) if offsets_deg is None else np.atleast_2d(offsets_deg)
    grid = np.stack(np.meshgrid(tilts_deg, azimuths_deg, distances_m, rolls_deg, np.arange(len(offsets)),
                                indexing="ij"), -1).reshape(-1, 5)  # fmt: skip
    tilt, az, roll = np.radians(grid[:, 0]), np.radians(grid[:, 1]), np.radians(grid[:, 3])
    d = np.stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)], axis=1)
    eyes = np.asarray(target_base, float) + grid[:, 2:3] * d
    off = np.radians(offsets[grid[:, 4].astype(int)])
    # the target at angles (a right, b down): turn the camera by -a about its y axis, +b about its x axis
    R_off = Rotation.from_euler("yx", np.stack([-off[:, 0], off[:, 1]], axis=1)).as_matrix()
    T = look_at(eyes, target_base, roll)
    T[:, :3, :3] = T[:, :3, :3] @ R_off
    return T


def in_image(p_cam: np.ndarray, K: np.ndarray, size: tuple[int, int], margin_px: float) -> np.ndarray:
    """(n,) bool: camera-frame points (n, 3) in front of the camera and projecting at least
    ``margin_px`` inside an image of ``size`` = (width, height) with intrinsics K (3, 3)."""
    p = np.atleast_2d(p_cam)
    z = np.where(p[:, 2] > 1e-6, p[:, 2], np.nan)
    u = K[0, 0] * p[:, 0] / z + K[0, 2]
    v = K[1, 1] * p[:, 1] / z + K[1, 2]
    w, h = size
    ok = (u >= margin_px) & (u <= w - 1 - margin_px) & (v >= margin_px) & (v <= h - 1 - margin_px)
    return np.asarray(ok & np.isfinite(z))
