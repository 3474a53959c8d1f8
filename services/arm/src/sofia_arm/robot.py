"""The connection to the robot through franky: connect, reconnect, read its state at a fixed rate.

One thread reads the robot's state (``franky.Robot.state``: the newest state of the running motion,
or the next state the robot sends when idle), maps its time onto the bus clock, computes the
flange pose from the measured joints with the Panda kinematics and hands each :class:`Sample` to a
callback (the publisher). A lost connection is reported in :attr:`RobotLink.error` and the thread
reconnects by itself; motion is refused until ``recover``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import franky
import numpy as np
from sofia_schemas.kinematics import panda_fk

from .clock import ClockMap
from .config import ArmConfig

log = logging.getLogger(__name__)
REALTIME = {"ignore": franky.RealtimeConfig.Ignore, "enforce": franky.RealtimeConfig.Enforce}
HISTORY_S = 1.0


class RateMeter:
    """Events per second over the last second."""

    def __init__(self) -> None:
        self.times: list[float] = []

    def tick(self) -> None:
        now = time.monotonic()
        self.times.append(now)
        if self.times[0] < now - 2.0:
            self.times = [t for t in self.times if t >= now - 1.0]

    def hz(self) -> float:
        now = time.monotonic()
        return float(sum(1 for t in self.times if t >= now - 1.0))


@dataclass
class Sample:
    """One robot state. Frames: base = ``panda_link0``, flange = ``panda_link8``."""

    stamp_ns: int  # bus time of the robot's state
    robot_time_ns: int  # the robot's own time
    received_ns: int  # when this process read it
    q: np.ndarray  # (7,) measured joint positions, rad
    q_d: np.ndarray  # (7,) the joint positions commanded last, rad
    dq: np.ndarray  # (7,) measured joint velocities, rad/s
    tau: np.ndarray  # (7,) measured joint torques, Nm
    T_base_flange: np.ndarray  # (4, 4) Panda FK of q
    O_T_EE: np.ndarray  # (4, 4) the robot's end-effector pose
    F_T_EE: np.ndarray  # (4, 4) the robot's flange -> end-effector transform
    robot_mode: str
    errors: list[str] = field(default_factory=list)


def error_names(errors: object) -> list[str]:
    """The names of the set flags of a ``franky.Errors`` (its repr lists them: ``[a, b]``)."""
    text = str(errors).strip().strip("[]")
    return [e.strip() for e in text.split(",") if e.strip()]


def sample_of(state: franky.RobotState, clock: ClockMap, received_ns: int) -> Sample:
    q = np.array(state.q, dtype=np.float64)
    robot_ns = int(state.time.to_msec()) * 1_000_000
    return Sample(
        stamp_ns=clock.update(robot_ns, received_ns), robot_time_ns=robot_ns, received_ns=received_ns,
        q=q, q_d=np.array(state.q_d, dtype=np.float64), dq=np.array(state.dq, dtype=np.float64), tau=np.array(state.tau_J, dtype=np.float64),
        T_base_flange=panda_fk(q, check_limits=False), O_T_EE=np.array(state.O_T_EE.matrix),
        F_T_EE=np.array(state.F_T_EE.matrix), robot_mode=state.robot_mode.name,
        errors=error_names(state.current_errors),
    )  # fmt: skip


def stop_motion(robot: franky.Robot, dynamics: float) -> None:
    """Bring a moving robot to a stop with a stop motion of the running control type (libfranka's
    stop if that fails); nothing when it is not moving."""
    try:
        kind = robot.current_control_signal_type
        if kind is None:
            return
        if kind == franky.ControlSignalType.CartesianPose:
            robot.move(franky.CartesianStopMotion(dynamics), asynchronous=True)
        else:
            robot.move(franky.JointStopMotion(dynamics), asynchronous=True)
    except Exception as e:  # a stop must not fail: fall back to libfranka's stop
        log.warning("stop motion failed (%s), stopping the robot", e)
        try:
            robot.stop()
        except Exception as e2:
            log.error("robot.stop failed: %s", e2)


class RobotLink:
    """franky's Robot plus a state thread. ``robot`` is None while disconnected."""

    def __init__(
        self, host: str, config: ArmConfig, on_sample: Callable[[Sample], None] | None = None
    ) -> None:
        self.host = host
        self.config = config
        self.on_sample = on_sample
        self.robot: franky.Robot | None = None
        self.error: str | None = None  # why the connection was lost (cleared by recover)
        self.latest: Sample | None = None
        self.history: deque[Sample] = deque()
        self.clock = ClockMap()
        self.rate = RateMeter()
        self.counters = {"states": 0, "read_errors": 0, "connects": 0, "disconnects": 0}
        self.connected = threading.Event()
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        # lost connections' Robots, kept: franky's destructor joins the control thread, which
        # waits forever when the robot never answers the running motion, and would hang its caller
        self._lost: list[franky.Robot] = []

    # --- connection ---------------------------------------------------------
    def connect(self) -> franky.Robot:
        """Connect (raises franky's exception when the robot does not answer) and set it up."""
        c = self.config
        robot = franky.Robot(
            self.host, relative_dynamics_factor=1.0, default_torque_threshold=c.torque_threshold_nm,
            default_force_threshold=c.force_threshold_n, realtime_config=REALTIME[c.realtime],
        )  # fmt: skip
        robot.set_collision_behavior(c.torque_threshold_nm, c.force_threshold_n)
        self.robot = robot
        self.counters["connects"] += 1
        self.connected.set()
        log.info("connected to the robot at %s", self.host)
        return robot

    def lost(self, reason: str) -> None:
        """Mark the connection lost (the state thread reconnects)."""
        if self.robot is not None:
            log.error("robot connection lost: %s", reason)
            self.counters["disconnects"] += 1
            self._lost.append(self.robot)
        self.robot = None
        self.connected.clear()
        self.error = f"connection to the robot at {self.host} lost: {reason}"

    # --- state thread -------------------------------------------------------
    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="arm-state", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.robot = None

    def _run(self) -> None:
        period = 1.0 / self.config.state_rate_hz
        next_t = time.monotonic()
        last_robot_ns = -1
        while not self._stop.is_set():
            robot = self.robot
            if robot is None:
                try:
                    robot = self.connect()
                except franky.RealtimeException as e:  # --realtime enforce without an RT kernel
                    if self.error is None:
                        log.error("cannot control the robot at %s: %s", self.host, e)
                    self.error = f"real-time priority required (--realtime enforce) but refused: {e}"
                    self._stop.wait(self.config.reconnect_period_s)
                    continue
                except Exception as e:  # franky raises its own exception types
                    log.debug("robot at %s not reachable: %s", self.host, e)
                    self._stop.wait(self.config.reconnect_period_s)
                    continue
            try:
                state = robot.state
            except franky.InvalidOperationException:  # a motion started between check and read
                continue
            except Exception as e:
                self.counters["read_errors"] += 1
                self.lost(f"{type(e).__name__}: {e}")
                continue
            received_ns = time.time_ns()
            sample = sample_of(state, self.clock, received_ns)
            if sample.robot_time_ns != last_robot_ns:
                last_robot_ns = sample.robot_time_ns
                self._keep(sample)
                if self.on_sample is not None:
                    self.on_sample(sample)
            next_t += period
            delay = next_t - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                next_t = time.monotonic()

    def _keep(self, sample: Sample) -> None:
        with self._cond:
            if self.latest is not None and sample.robot_time_ns < self.latest.robot_time_ns:
                self.history.clear()  # the robot restarted: its clock began anew
            self.latest = sample
            self.history.append(sample)
            while self.history[0].robot_time_ns < sample.robot_time_ns - int(HISTORY_S * 1e9):
                self.history.popleft()
            self.counters["states"] += 1
            self.rate.tick()
            self._cond.notify_all()

    # --- measurements -------------------------------------------------------
    def robot_rate_hz(self) -> float:
        """Robot states produced per second over the last second (its clock's ticks: 1 kHz on a
        real robot; a simulator on a busy machine runs slower)."""
        samples = self.window(1.0)
        if len(samples) < 2:
            return 0.0
        wall_s = (samples[-1].received_ns - samples[0].received_ns) * 1e-9
        return (samples[-1].robot_time_ns - samples[0].robot_time_ns) * 1e-6 / max(wall_s, 1e-3)

    def window(self, seconds: float) -> list[Sample]:
        """The samples of the last ``seconds`` of the robot's clock."""
        with self._cond:
            if not self.history:
                return []
            t_end = self.history[-1].robot_time_ns
            return [s for s in self.history if s.robot_time_ns >= t_end - int(seconds * 1e9)]

    def wait_sample(self, after_ns: int, timeout: float) -> Sample | None:
        """The first sample stamped after ``after_ns`` (None on timeout)."""
        with self._cond:
            ok = self._cond.wait_for(
                lambda: self.latest is not None and self.latest.stamp_ns > after_ns, timeout
            )
            return self.latest if ok else None

    def mean_q(self, seconds: float = 0.1) -> np.ndarray | None:
        """Joint positions (7,) averaged over the last ``seconds`` (measurement noise and the
        simulator's joint chatter average out); None without samples."""
        samples = self.window(seconds)
        return np.mean([s.q for s in samples], axis=0) if samples else None

    def is_still(self, speed_rad_s: float, seconds: float = 0.3) -> bool:
        """True when the mean joint speed over the last ``seconds`` of the robot's clock (the first
        half's mean position against the second half's) is below ``speed_rad_s`` on every joint;
        averaging makes it robust to measurement noise (franky-sim's wrist chatters)."""
        samples = self.window(seconds)
        if len(samples) < 6 or (samples[-1].robot_time_ns - samples[0].robot_time_ns) < 0.8 * seconds * 1e9:
            return False
        q = np.array([s.q for s in samples])
        t = np.array([s.robot_time_ns for s in samples]) * 1e-9
        h = len(q) // 2
        dt = t[h:].mean() - t[:h].mean()
        speed = np.abs(q[h:].mean(axis=0) - q[:h].mean(axis=0)) / max(dt, 1e-6)
        return bool(np.all(speed < speed_rad_s))
