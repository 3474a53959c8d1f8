"""The gripper and its commands: each returns a :class:`GripperResult` when done, failed or timed out.

Bad arguments and impossible requests raise :class:`~sofia_gripper.errors.CommandError` (the
service turns them into error replies); a command that starts and then fails returns
``ok=False`` with the reason.
"""

from __future__ import annotations

import logging
import time

from sofia_schemas.messages import GripperCommand, GripperResult, GripperState

from .driver import GripperDriver
from .errors import CommandError, GripperError, NotReady, OutOfRange

log = logging.getLogger(__name__)
GRASP_CURRENT_FRACTION = 0.7  # stalled with at least this share of the goal current = object held
STALL_VELOCITY_RAD_S = 0.05  # about two units of Present Velocity: "not moving" for stall detection
MOTION = {"open", "close", "move", "grasp", "release"}


class Gripper(GripperDriver):
    """An MX-64 gripper on a serial line that runs :class:`GripperCommand` s."""

    def execute(self, cmd: GripperCommand, clear_abort: bool = True) -> GripperResult:
        """Run ``cmd``. ``clear_abort=False``: the caller cleared ``abort`` itself (under its
        own lock, so a stop arriving after that point still ends this command)."""
        return _execute(self, cmd, clear_abort)


def _execute(g: GripperDriver, cmd: GripperCommand, clear_abort: bool = True) -> GripperResult:
    """Run ``cmd`` on gripper ``g`` (see :meth:`Gripper.execute`)."""
    t0 = time.monotonic()
    g.counters["commands"] += 1
    if cmd.action == "state":
        return _result(cmd, True, "done", g.state, t0)
    if cmd.action == "stop":
        g.abort.set()
        _require_connected(g)
        state = g.state
        if state.position_ticks is not None:  # through write_goal: a tripped Bus Watchdog is cleared
            g.servo.write_goal("goal_position", state.position_ticks)
        return _result(cmd, True, "done", g.next_state(0.5) or g.state, t0)
    with g.command_lock:
        if clear_abort:
            g.abort.clear()
        if cmd.action == "torque":
            return _torque(g, cmd, t0)
        if cmd.action == "reboot":
            return _reboot(g, cmd, t0)
        return _motion(g, cmd, t0)


def _require_connected(g: GripperDriver) -> None:
    if not g.connected:
        raise NotReady(f"serial line down ({g.error})")


def _torque(g: GripperDriver, cmd: GripperCommand, t0: float) -> GripperResult:
    if cmd.enable is None:
        raise CommandError("torque needs 'enable': true or false")
    _require_connected(g)
    if cmd.enable and g.config.protocol == 2 and g.hw_error:
        raise NotReady(
            f"reboot needed: the servo shut down on {', '.join(g.hw_error)} and only a reboot re-enables its torque"
        )
    if cmd.enable:
        g.servo.write_goal("goal_position", g.bus.read("present_position"))
        if g.config.protocol == 1:  # "Alarm Shutdown" set Torque Limit(34) to 0: writing it re-arms
            g.servo.set_current(g.config.move_current_ma)
    g.bus.write("torque_enable", int(cmd.enable))
    # Protocol 2.0 e-Manual, "Shutdown(63)": after a shutdown only REBOOT re-enables the torque; the
    # servo takes the write and switches it off again, so the answer is what the servo reads back
    g.torque = cmd.enable and g.bus.read("torque_enable") == 1
    g.grasped = g.grasped and g.torque
    if cmd.enable and not g.torque:
        return _result(
            cmd, False, "reboot needed: the servo switched its torque off again (a shutdown)", g.state, t0
        )
    return _result(cmd, True, "done", g.next_state(0.5) or g.state, t0)


def _reboot(g: GripperDriver, cmd: GripperCommand, t0: float) -> GripperResult:
    _require_connected(g)
    g.bus.reboot()
    deadline = t0 + cmd.timeout_s
    while True:
        try:
            g.bus.ping()
            break
        except GripperError:
            if time.monotonic() > deadline:
                return _result(cmd, False, "timeout: servo did not answer after reboot", g.state, t0)
            time.sleep(0.05)
    g.grasped = False
    g.configure()
    g.connected, g.error = True, None
    state = g.next_state(0.5) or g.state
    state = g.next_state(0.5) or state
    if state.hardware_error:
        return _result(cmd, False, f"hardware error persists after reboot: {state.hardware_error}", state, t0)
    return _result(cmd, True, "done", state, t0)


def _target(g: GripperDriver, cmd: GripperCommand) -> float:
    """Goal in ticks; out-of-range requests are refused, tiny overshoots clamped."""
    c = g.config
    if cmd.action in ("open", "release"):
        return c.open_ticks
    if cmd.action in ("close", "grasp"):
        return c.closed_ticks
    if cmd.opening_mm is not None and cmd.position_ticks is not None:
        raise CommandError("move takes opening_mm or position_ticks, not both")
    if cmd.position_ticks is not None:
        low, high = g.servo.limits
        if not low <= cmd.position_ticks <= high:
            raise OutOfRange("move position", cmd.position_ticks, low, high, "ticks")
        return cmd.position_ticks
    if cmd.opening_mm is not None:
        closed_mm, open_mm = float(g.kin.opening(c.closed_ticks)), float(g.kin.opening(c.open_ticks))
        if not closed_mm - 0.5 <= cmd.opening_mm <= open_mm + 0.5:
            raise OutOfRange("move opening", cmd.opening_mm, closed_mm, open_mm, "mm")
        return float(g.kin.ticks(cmd.opening_mm))
    raise CommandError("move needs opening_mm or position_ticks")


def _current(g: GripperDriver, cmd: GripperCommand) -> float:
    c = g.config
    if cmd.action != "grasp":
        if cmd.force_n is not None or cmd.current_ma is not None:
            raise CommandError(f"{cmd.action} takes no force_n/current_ma (only grasp does)")
        return c.move_current_ma
    if cmd.force_n is not None and cmd.current_ma is not None:
        raise CommandError("grasp takes force_n or current_ma, not both")
    current = c.grasp_current_ma
    max_force = g.servo.current_limit_ma / 1000 * c.force_per_amp_n
    if cmd.force_n is not None:
        current = cmd.force_n / c.force_per_amp_n * 1000
        if current > g.servo.current_limit_ma:
            raise OutOfRange("grasp force", cmd.force_n, 0, max_force, "N")
    elif cmd.current_ma is not None:
        current = cmd.current_ma
    if current > g.servo.current_limit_ma:
        raise OutOfRange(
            "grasp current", current, 0, g.servo.current_limit_ma, f"mA (force limit {max_force:g} N)"
        )
    return current


def _motion(g: GripperDriver, cmd: GripperCommand, t0: float) -> GripperResult:
    target, current = _target(g, cmd), _current(g, cmd)
    _require_connected(g)
    if g.hw_error:
        raise NotReady(f"hardware error {g.hw_error}; {g.recover_hint}")
    if g.overheated:
        raise NotReady(f"temperature above {g.config.max_temperature_c:g} C")
    if not g.torque:
        raise NotReady("torque is off; send torque with enable=true")
    trips = g.counters["watchdog_trips"]  # before the goals: a trip recovered meanwhile resends them
    goal = _send_goals(g, cmd, target, current)
    g.grasped = False
    return _wait(g, cmd, goal, current, t0, trips)


def _send_goals(g: GripperDriver, cmd: GripperCommand, target: float, current: float) -> int:
    g.servo.set_current(current)
    g.servo.set_speed(cmd.speed or 1.0)
    return g.servo.set_goal(target)


def _wait(
    g: GripperDriver, cmd: GripperCommand, goal: int, current: float, t0: float, trips: int
) -> GripperResult:
    """Wait for the goal or a stall. A stall is detected from the motion itself (speed about 0
    and either the current at the goal current, or the profile over short of the goal) for
    ``stall_time_s``, not from Moving: the servo keeps Moving at 1 until its profile ends, even
    when an object stopped the fingers (e-Manual, "Moving(122)"). ``trips``: the watchdog trips
    counted before the goals were sent; a trip after that (the servo then drops its goal) resends
    them, as does a stop short of the goal whose Goal Position the servo no longer holds."""
    c = g.config
    deadline = t0 + cmd.timeout_s
    still_since: float | None = None
    while True:
        state = g.next_state(0.5)
        now = time.monotonic()
        if state is None and g.connected and now <= deadline:
            continue  # the state loop was held up (a host stall), the line is not lost
        if state is None or not state.connected:
            return _result(cmd, False, f"serial line lost ({g.error})", g.state, t0)
        if state.status == "error":
            return _result(cmd, False, state.error or "error", state, t0)
        if g.abort.is_set():  # hold where we are, even if our goal was written after the stop's
            g.servo.write_goal("goal_position", state.position_ticks or goal)
            return _result(cmd, False, "stopped by a stop command", state, t0)
        if now > deadline:
            g.servo.write_goal("goal_position", state.position_ticks or goal)
            return _result(cmd, False, f"timeout after {cmd.timeout_s:g} s", state, t0)
        if g.counters["watchdog_trips"] != trips:  # the servo stopped on a trip: send the goals again
            trips = g.counters["watchdog_trips"]
            log.warning("gripper %s: resending goals after a bus watchdog trip", cmd.action)
            _send_goals(g, cmd, goal, current)
            still_since = None
            continue
        pos = state.position_ticks or 0
        if abs(pos - goal) <= c.position_tolerance_ticks:
            if not state.moving:
                return _result(cmd, True, "done", state, t0, grasped=False if cmd.action == "grasp" else None)
            still_since = None
            continue
        squeezing = (state.current_ma or 0.0) >= GRASP_CURRENT_FRACTION * current
        slow = abs(state.velocity_rad_s or 0.0) <= STALL_VELOCITY_RAD_S
        if not (slow and (squeezing or not state.moving)) or now - t0 < 2 * c.stall_time_s:
            still_since = None
            continue
        still_since = still_since or now
        if now - still_since < c.stall_time_s:
            continue
        if not squeezing and (g.servo.recover_watchdog() or g.bus.read("goal_position") != goal):
            log.warning(
                "gripper %s: the servo dropped its goal (a watchdog trip); sending it again", cmd.action
            )
            trips = g.counters["watchdog_trips"]
            _send_goals(g, cmd, goal, current)
            still_since = None
            continue
        if cmd.action in ("grasp", "close") and squeezing:
            g.grasped = True
            return _result(cmd, True, "stalled", state.model_copy(update={"grasped": True}), t0, grasped=True)
        blocked = f"blocked at {state.opening_mm or 0.0:.1f} mm before the goal (current {state.current_ma or 0.0:.0f} mA)"
        return _result(cmd, False, blocked, state, t0, grasped=False)


def _result(
    cmd: GripperCommand, ok: bool, reason: str, state: GripperState, t0: float, grasped: bool | None = None
) -> GripperResult:
    if not ok:
        log.warning("gripper %s failed: %s", cmd.action, reason)
    return GripperResult(
        action=cmd.action, ok=ok, reason=reason, grasped=grasped, opening_mm=state.opening_mm,
        duration_s=time.monotonic() - t0, state=state,
    )  # fmt: skip
