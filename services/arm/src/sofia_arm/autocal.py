"""Autonomous hand-eye calibration: the arm shows the blob to the camera from poses chosen to
shrink the calibrator's covariance most, until the translation 1-sigma is below the target.

Steps: (1) orient: without a guess of ``T_flange_cam``, the table plane seen from flange tilts about
two axes gives the camera's rotation on the flange (:func:`sofia_arm.plan.rotation_from_table`);
(2) find the blob (given, or seen on the way); (3) loop: rank candidate views of the blob by the
covariance they leave (:func:`sofia_arm.plan.rank_candidates`), go to the best reachable one, wait
until still, take the blob from the next camera frame with the flange pose of that instant, add the
sample to the calibrator and re-solve; the estimate steers the next views. A coloured ball on the
table can stand in for the blob (:class:`BallAutocal`); eye-to-hand, a ball on the flange
(:class:`FixedAutocal`).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import zenoh
from sofia_calibrator.errors import CalibrationError
from sofia_runtime.client import QueryError
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ArmCommand, ArmResult, CalibrationResult
from sofia_schemas.messages.arm import VIEW_WITHOUT_SAMPLE
from sofia_schemas.transforms import apply, invert

from . import autocal_fixed as fixed
from . import plan
from .autocal_io import BusCalibrator, BusEye, CalibratorLink, Eye, Progress
from .autocal_look import AutocalError, BallLooker, Looker
from .autocal_options import AutocalOptions, Outcome, to_arm_result
from .motion import ArmMotion
from .poses import Reach, in_image, solve_ik, views_of

log = logging.getLogger("sofia.arm.autocal")
__all__ = ["Autocal", "AutocalError", "AutocalOptions", "BallAutocal", "FixedAutocal", "Outcome",
           "run_autocal"]  # fmt: skip
MAX_OFFSET_M = 0.25  # a camera on the flange is closer than this to the flange origin
TRUST_SIGMA_MM = 5.0  # the calibrator's estimate steers the views once the model predicts this 1-sigma
# where the blob may be put in the image (right, down; degrees): off-centre views observe the
# camera's rotation about its optical axis
IMAGE_OFFSETS_DEG = np.array([[0, 0], [12, 0], [-12, 0], [0, 9], [0, -9], [9, 7], [-9, -7], [9, -7], [-9, 7]])
D435_K = np.array([[615.0, 0.0, 319.5], [0.0, 615.0, 239.5], [0.0, 0.0, 1.0]])


class Autocal(Looker):
    """One autonomous calibration run (:meth:`run`): eye-in-hand, the blob on the table."""

    def __init__(self, arm: ArmMotion, eye: Eye, cal: CalibratorLink, opts: AutocalOptions,
                 progress: Progress, reach: Reach | None = None, K: np.ndarray = D435_K,
                 image_size: tuple[int, int] = (640, 480)) -> None:  # fmt: skip
        super().__init__(arm, eye, opts, progress, reach or Reach())
        self.cal, self.K, self.image_size = cal, K, image_size
        self.samples_T: list[np.ndarray] = []
        self.samples_p: list[np.ndarray] = []
        self.trusted = False  # the calibrator's estimate steers the views (else the rough one)
        self.result: CalibrationResult | None = None

    # --- 2. the views ---------------------------------------------------------------------------
    def candidates(self, first: bool) -> np.ndarray:
        """(m, 4, 4) flange poses viewing the blob under the current estimate, blob in the image."""
        assert self.T_fc is not None and self.p_base is not None
        lo, hi = self.opts.distance_m
        dists = np.array([max(lo, hi - 0.15), hi]) if first else np.linspace(lo, hi, 4)
        offsets = IMAGE_OFFSETS_DEG[:5] / 2 if first else IMAGE_OFFSETS_DEG
        T_bc = views_of(self.p_base, np.linspace(0, self.opts.max_tilt_deg, 4), np.arange(0, 360, 45),
                        dists, np.arange(0, 360, 60), offsets)  # fmt: skip
        T_bf = T_bc @ invert(self.T_fc)
        p_cam = apply(invert(T_bf @ self.T_fc), np.broadcast_to(self.p_base, (len(T_bf), 3)))
        in_view = in_image(p_cam, self.K, self.image_size, self.opts.margin_px)
        return np.asarray(T_bf[self.reach.in_box(T_bf[:, :3, 3]) & in_view])

    def model_poses(self, T_base_flange: np.ndarray) -> np.ndarray:
        """(n, 4, 4) the poses of the calibrator's model for flange poses (n, 4, 4): themselves
        eye-in-hand (eye-to-hand inverts them, :class:`sofia_arm.autocal_fixed.FixedAutocal`)."""
        return T_base_flange

    def information(self) -> np.ndarray:
        assert self.T_fc is not None and self.p_base is not None
        info = plan.prior_information()
        if self.samples_T:
            poses = self.model_poses(np.array(self.samples_T))
            info = info + plan.information(poses, self.T_fc, self.p_base).sum(axis=0)
        return info

    def next_pose(self, tried: list[np.ndarray]) -> np.ndarray | None:
        assert self.T_fc is not None and self.p_base is not None
        cands = self.candidates(first=not self.trusted)
        if tried:  # not the same view twice
            d = np.linalg.norm(cands[:, None, :3, 3] - np.array(tried)[None, :, :3, 3], axis=2).min(axis=1)
            cands = cands[d > 0.01]
        ranked = plan.rank_candidates(self.information(), self.model_poses(cands), self.T_fc, self.p_base)
        q_now = self.arm.q()  # a joint path taking the tool below the surface is refused: skipped
        for i in ranked.order[:25]:
            ik = solve_ik(cands[i], q_now, self.reach, n_random_seeds=2)
            if ik.ok and self.reach.path_clear(q_now, ik.q):
                return np.asarray(cands[i])
        return None

    def rough_update(self) -> None:
        """Before the calibrator's estimate is trusted: the camera's rotation is known (table), so
        the offset is linear; kept when well conditioned and plausible."""
        if self.T_fc is None or len(self.samples_T) < 3:
            return
        lin = plan.offset_given_rotation(
            np.array(self.samples_T), self.T_fc[:3, :3], np.array(self.samples_p), min_singular=0.15
        )
        if lin is not None and np.linalg.norm(lin[0]) < MAX_OFFSET_M:
            self.T_fc[:3, 3], self.p_base = lin

    def take(self, step: str) -> tuple[bool, str]:
        """Look from where the arm is and add the sample: (taken, one progress line)."""
        T_bf, frame = self._look(step)
        K = plan.intrinsics_of(frame.points_cam)
        if K is not None:  # the views of the next poses use the camera's own image
            self.K, self.image_size = K, (frame.points_cam.shape[1], frame.points_cam.shape[0])
        if frame.rgb is None:
            raise AutocalError(step, "the camera frames have no colour")
        try:
            p_cam, confidence, text = self.observe(frame)
        except CalibrationError as e:
            return False, f"no {self.TARGET}: {e}"
        self.cal.add(frame.stamp_ns, p_cam, T_bf, confidence)
        self.samples_T.append(T_bf)
        self.samples_p.append(p_cam)
        return True, text

    def sample_at(self, T_target: np.ndarray, k: int) -> tuple[bool, str]:
        """Visit a view and add its sample: (taken, what happened as one progress line)."""
        if not self._go(T_target, f"pose {k}"):
            return False, "unreachable"
        ok, text = self.take(f"pose {k}")
        if not ok:
            return False, text
        if not self.trusted:
            self.rough_update()
        if len(self.samples_T) >= 3:
            try:
                self.result = self.cal.solve()
            except QueryError as e:
                return True, f"{text}; not solved yet: {e}"
            self.trusted = self.trusted or self.model_sigma_mm().max() < TRUST_SIGMA_MM
            if self.trusted:  # the views pin the calibrator's estimate: steer by it
                self.T_fc = np.array(self.result.matrix)
                self.p_base = np.array(self.result.target_base)
            s, m = (np.array2string(np.asarray(v), separator=", ", floatmode="fixed", precision=2)
                    for v in (self.result.std_translation_mm, self.model_sigma_mm()))  # fmt: skip
            text += f"; 1-sigma t {s} mm (model {m})"
        return True, text

    def model_sigma_mm(self) -> np.ndarray:
        """(3,) 1-sigma of t_fc (flange axes, mm) the D435 noise model predicts for the samples taken."""
        return plan.translation_sigma_mm(self.information() - plan.prior_information() + 1e-9 * np.eye(9))

    def sigma_mm(self) -> np.ndarray:
        """(3,) the translation 1-sigma the stop rule uses and the outcome reports: the calibrator's
        reported one, never below the noise model's prediction. At the stop (about 6 samples) the
        calibrator's alone covers the error a third of the time, this one 60 % (``bench_autocal``)."""
        if self.result is None:
            return np.full(3, np.inf)
        return np.maximum(np.array(self.result.std_translation_mm), self.model_sigma_mm())

    def done(self) -> bool:
        return (
            len(self.samples_T) >= self.opts.min_poses
            and float(self.sigma_mm().max()) < self.opts.target_sigma_mm
        )

    def start(self) -> None:
        """What the views need first: the camera's rotation (table) and the blob's position."""
        if self.T_fc is None:
            self.orient()
        if self.p_base is None:
            self.find()

    def run(self) -> Outcome:
        t0 = time.monotonic()
        q_start = self.arm.q()
        self.cal.reset()
        self.start()
        visits, failures, tried = 0, 0, list[np.ndarray]()
        stop = f"pose budget of {self.opts.max_poses} spent"
        while len(self.samples_T) < self.opts.max_poses:
            T = self.next_pose(tried)
            if T is None:
                stop = "no reachable view left"
                break
            tried.append(T)
            visits += 1
            t = time.monotonic()
            ok, text = self.sample_at(T, len(self.samples_T) + 1)
            failures = 0 if ok else failures + 1
            name = (
                f"pose {len(self.samples_T)}/{self.opts.max_poses}"
                if ok
                else f"{VIEW_WITHOUT_SAMPLE} {visits}"
            )
            self.progress.add(name, "done" if ok else "failed", text, time.monotonic() - t)
            if failures >= self.opts.max_failures:
                raise AutocalError("views", f"{failures} views in a row without a sample ({text})")
            if self.done():
                stop = f"translation 1-sigma below {self.opts.target_sigma_mm} mm"
                break
        if self.opts.return_to_start:
            self.go_back(q_start)
        log.info("autonomous calibration: %d samples, %d visits, %.1f s: %s", len(self.samples_T), visits,
                 time.monotonic() - t0, stop)  # fmt: skip
        sigma = self.sigma_mm() if self.result is not None else None
        return Outcome(self.result, len(self.samples_T), visits, self.samples_T, stop, sigma)


class BallAutocal(BallLooker, Autocal):
    """Eye-in-hand with a coloured ball lying on the table in place of the blob: the same run, the
    ball's centre (a sphere fit, :mod:`sofia_calibrator.targets.ball`) as each view's point. With
    the radius unknown, every sample's centre is refitted with one radius shared by all the views
    each time one is added, and the calibrator's samples replaced by them."""

    def take(self, step: str) -> tuple[bool, str]:
        ok, text = super().take(step)
        if not ok or self.last_seen is None:
            return ok, text
        stamp_ns, ball = self.last_seen
        self.segments.append(ball.segment)
        self.seen.append((stamp_ns, ball.confidence))
        radius = self.refit(self.samples_p)
        if radius is None:
            return ok, text
        self.cal.reset()
        for (stamp, conf), p_cam, T_bf in zip(self.seen, self.samples_p, self.samples_T, strict=True):
            self.cal.add(stamp, p_cam, T_bf, conf)
        return ok, f"{text}; radius {1e3 * radius:.2f} mm shared by {len(self.seen)} views"


class FixedAutocal(BallAutocal):
    """Eye-to-hand: a fixed camera, a ball on the flange (:mod:`sofia_arm.autocal_fixed`).
    ``T_fc`` holds T_base_cam and ``p_base`` the ball's centre in the flange frame."""

    R_start: np.ndarray | None = None  # (3, 3) the flange's orientation at the start (base frame)

    def model_poses(self, T_base_flange: np.ndarray) -> np.ndarray:
        return fixed.inverse_poses(T_base_flange)

    def rough_update(self) -> None:
        """Nothing: the start's estimate steers until the calibrator's is trusted."""

    def start(self) -> None:
        """Without a guess: the ball seen from the start pose and from small shifts and turns of
        the flange (every one a sample) gives a rough ``T_base_cam`` and ball position."""
        T_start = self.arm.T_base_flange()
        self.R_start = T_start[:3, :3].copy()
        if self.T_fc is not None and self.p_base is not None:
            return
        ok, text = self.take("find ball")
        if not ok:
            raise AutocalError("find ball", f"the fixed camera does not see the ball at the start pose ({text})")  # fmt: skip
        self.progress.add("find ball", "done", text)
        for name, T in fixed.start_moves(T_start):
            if self._go(T, name):
                ok, text = self.take(name)
                self.progress.add(name, "done" if ok else "failed", text)
        rough = fixed.rough_fixed(np.array(self.samples_T), np.array(self.samples_p))
        if rough is None:
            raise AutocalError("find camera", f"the ball was seen in {len(self.samples_T)} start views, too few "
                               "shifts and turns: start where the flange can move 6 cm and turn 25 deg")  # fmt: skip
        self.T_fc, self.p_base = rough
        self.progress.add("find camera", "done", f"camera near {np.round(self.T_fc[:3, 3], 3).tolist()} m (base), "
                          f"ball near {np.round(self.p_base, 3).tolist()} m (flange)")  # fmt: skip

    def candidates(self, first: bool) -> np.ndarray:
        assert self.T_fc is not None and self.p_base is not None
        R_start = self.arm.T_base_flange()[:3, :3] if self.R_start is None else self.R_start
        return fixed.fixed_candidates(self.T_fc, self.p_base, R_start, self.reach, self.opts.distance_m,
                                      self.K, self.image_size, self.opts.margin_px)  # fmt: skip


def run_autocal(cmd: ArmCommand, arm: ArmMotion, session: zenoh.Session, keys: Keys) -> ArmResult:
    """The arm service's ``calibrate`` command (options in ``cmd.calibrate``)."""
    t0 = time.monotonic()
    opts = AutocalOptions.from_dict(cmd.calibrate, cmd.speed)
    progress = Progress(session, keys)
    eye = BusEye(session, keys)
    try:
        safety = getattr(arm, "safety", None)  # the service's tool and surface rule, for every view
        reach = None if safety is None else safety.planner_reach(Reach())
        cal = BusCalibrator(session, keys, setup=opts.setup)
        kind = (
            FixedAutocal if opts.setup == "eye-to-hand" else BallAutocal if opts.target == "ball" else Autocal
        )
        run = kind(arm, eye, cal, opts, progress, reach)
        try:
            outcome = run.run()
        except AutocalError as e:
            progress.add(e.step, "failed", e.reason)
            return to_arm_result(arm, None, progress, time.monotonic() - t0, str(e))
        return to_arm_result(arm, outcome, progress, time.monotonic() - t0, "")
    finally:
        eye.close()
        progress.close()
