"""The gripper driver: connection, state loop, safety, reconnect.

One thread owns the state loop: one Sync/Bulk Read per cycle, decoded into a
:class:`GripperState` and handed to ``on_state``. Commands (:mod:`.commands`, on top of this
module) write goals through :attr:`GripperDriver.servo` (:mod:`.servo`) and wait for the loop's
states. When the serial line fails the state says ``disconnected`` with no stale values, and the
loop reconnects every ``reconnect_period_s``.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from typing import Literal

from sofia_schemas.messages import GripperState, now_ns

from .bus import DxlBus
from .config import GripperConfig
from .control_table import MODEL, STATE_BLOCK, decode_int, hardware_error_words
from .errors import BusError, GripperError, WrongModel
from .servo import Servo

log = logging.getLogger(__name__)
FAILS_BEFORE_LOST = 3
LOST_AFTER_S = 0.3  # ... and failing for at least this long


class GripperDriver:
    """An MX-64 gripper on a serial line. ``start()`` connects and runs the state loop."""

    def __init__(self, config: GripperConfig, on_state: Callable[[GripperState], None] | None = None) -> None:
        self.config, self.on_state = config, on_state
        self.kin = config.kinematics()
        self.bus = DxlBus(config.port, config.baud, config.protocol, config.dxl_id, config.reply_margin_ms)
        self.counters = {"cycles": 0, "read_errors": 0, "reconnects": 0, "commands": 0, "watchdog_trips": 0}
        self.servo = Servo(self.bus, config, self.counters)
        self.cond = threading.Condition()
        self.state = GripperState(stamp_ns=now_ns(), connected=False, status="disconnected")
        self.seq = 0
        self.connected = False
        self.hw_error: list[str] = []
        self.overheated = False
        self.torque = False
        self.grasped = False
        self.error: str | None = "not connected yet"
        self.abort = threading.Event()
        self.command_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._fails = 0
        self._first_fail = 0.0
        self._last_attempt = 0.0

    # --- lifecycle --------------------------------------------------------
    def start(self) -> None:
        try:
            self.connect()
        except GripperError as e:
            log.error(
                "gripper start-up failed: %s (retrying every %.1f s)", e, self.config.reconnect_period_s
            )
            self.error = str(e)
        self._thread = threading.Thread(target=self._loop, name="gripper-state", daemon=True)
        self._thread.start()

    def close(self, torque_off: bool = True) -> None:
        self._stop.set()
        if self._thread:
            self._thread.join(2.0)
        if torque_off and self.connected:
            try:
                self.bus.write("torque_enable", 0)
            except GripperError as e:
                log.warning("torque off at close failed: %s", e)
        self.connected = False
        self.bus.close()

    def connect(self) -> None:
        """Ping, check the model, configure and enable the torque."""
        self._last_attempt = time.monotonic()
        self.bus.open()
        model = self.bus.ping()
        expected = MODEL[self.config.protocol]
        if model != expected:
            raise WrongModel(self.config.dxl_id, model, expected)
        self.configure()
        self.connected, self._fails, self.error = True, 0, None
        log.info(
            "MX-64 id %d connected on %s (protocol %d)",
            self.config.dxl_id,
            self.config.port,
            self.config.protocol,
        )

    def configure(self) -> None:
        """Read limits, set the operating mode and currents, arm the watchdog, torque on."""
        self.servo.configure()
        self.torque, self.hw_error, self.overheated = True, [], False

    @property
    def recover_hint(self) -> str:
        """How to clear the present hardware error."""
        p2 = self.config.protocol == 2
        if "input_voltage" in self.hw_error:
            return "check the supply: the MX-64 needs 10-14.8 V" + (", then send reboot" if p2 else "")
        if p2:
            return "send reboot"
        return "send torque on (rewrites Torque Limit, which the servo's shutdown set to 0)"

    # --- state loop -------------------------------------------------------
    def _loop(self) -> None:
        period = 1.0 / self.config.state_rate_hz
        t_next = time.monotonic()
        while not self._stop.is_set():
            if self.connected:
                self._cycle()
            elif (
                time.monotonic() - self._last_attempt >= self.config.reconnect_period_s
                and self.command_lock.acquire(blocking=False)
            ):  # a running command (e.g. a reboot) owns the line until it returns
                try:
                    self._reconnect()
                finally:
                    self.command_lock.release()
            else:
                self._publish(self._disconnected_state())
            t_next = max(t_next + period, time.monotonic() - period)
            self._stop.wait(max(0.0, t_next - time.monotonic()))

    def _reconnect(self) -> None:
        try:
            self.connect()
            self.counters["reconnects"] += 1
        except GripperError as e:
            self.error = f"{e}"
            self.bus.close()
            self._publish(self._disconnected_state())

    def _cycle(self) -> None:
        try:
            block, status_error = self.bus.read_state()
            if status_error and self.config.protocol == 2:
                self.hw_error = hardware_error_words(2, self.bus.read("hardware_error_status"))
            elif self.config.protocol == 1:
                self.hw_error = hardware_error_words(1, status_error)
            else:
                self.hw_error = []
            if self.hw_error or self.counters["cycles"] % 25 == 0:
                self.torque = self.bus.read("torque_enable") == 1 and (
                    self.config.protocol == 2 or self.bus.read("torque_limit") > 0
                )  # Protocol 1.0 shutdown sets Torque Limit to 0 and leaves Torque Enable on
                if self.torque:
                    self.servo.recover_watchdog()
                else:  # a shutdown (or torque off) lets go of whatever was held
                    self.grasped = False
        except BusError as e:
            self.counters["read_errors"] += 1
            self._fails += 1
            if self._fails == 1:
                self._first_fail = time.monotonic()
            # lost: several failed reads in a row over a while (a loaded host can delay a few replies)
            if self._fails >= FAILS_BEFORE_LOST and time.monotonic() - self._first_fail >= LOST_AFTER_S:
                log.error("gripper line lost: %s", e)
                self.connected, self.error = False, str(e)
                self.bus.close()
                self._publish(self._disconnected_state())
            return
        except GripperError as e:
            log.warning("state read refused: %s", e)
            return
        self._fails = 0
        self.counters["cycles"] += 1
        state = self._decode(block)
        self._safety(state)
        self._publish(state)

    def _decode(self, block: bytes) -> GripperState:
        u, t = self.servo.units, self.bus.table
        start = STATE_BLOCK[self.config.protocol][0]

        def get(name: str) -> int:
            return decode_int(block, t[name].address - start, t[name])

        ticks = get("present_position")
        vel = get("present_velocity")
        if u.direction_bit and vel & u.direction_bit:
            vel = -(vel & (u.direction_bit - 1))
        current_ma = (get("present_current") - u.current_offset) * u.current_ma
        error = self.error
        if self.hw_error:
            error = f"hardware error: {', '.join(self.hw_error)}; {self.recover_hint}"
        elif self.overheated:
            error = f"temperature above {self.config.max_temperature_c:g} C: motion stopped"
        status: Literal["ok", "moving", "error"] = "error" if error else ("moving" if get("moving") else "ok")
        return GripperState(
            stamp_ns=now_ns(), connected=True, status=status, position_ticks=ticks,
            position_rad=float(self.kin.ticks_to_rad(ticks)), opening_mm=float(self.kin.opening(ticks)),
            velocity_rad_s=vel * u.velocity_rpm * 2 * math.pi / 60, current_ma=current_ma,
            force_n=max(0.0, current_ma) / 1000 * self.config.force_per_amp_n,
            temperature_c=float(get("present_temperature")), voltage_v=get("present_input_voltage") * u.voltage_v,
            moving=bool(get("moving")), torque_enabled=self.torque, hardware_error=self.hw_error,
            grasped=self.grasped, error=error, watchdog_trips=self.counters["watchdog_trips"],
        )  # fmt: skip

    def _safety(self, state: GripperState) -> None:
        hot = (state.temperature_c or 0.0) > self.config.max_temperature_c
        if (hot and not self.overheated) or (self.hw_error and state.moving):
            log.error(
                "gripper stopping: temperature %s C, hardware error %s", state.temperature_c, self.hw_error
            )
            self.abort.set()
            try:
                self.bus.write("goal_position", state.position_ticks or 0)
            except GripperError as e:
                log.warning("stop after fault failed: %s", e)
        self.overheated = hot

    def _disconnected_state(self) -> GripperState:
        return GripperState(stamp_ns=now_ns(), connected=False, status="disconnected", error=self.error)

    def _publish(self, state: GripperState) -> None:
        with self.cond:
            self.state, self.seq = state, self.seq + 1
            self.cond.notify_all()
        if self.on_state:
            self.on_state(state)

    def next_state(self, timeout: float) -> GripperState | None:
        """Wait for the next state from the loop (None after ``timeout`` s)."""
        with self.cond:
            seq = self.seq
            if not self.cond.wait_for(lambda: self.seq != seq, timeout):
                return None
            return self.state
