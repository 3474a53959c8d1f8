"""An MX-64 on a pseudo-terminal: speaks Dynamixel Protocol 2.0 or 1.0 byte for byte.

``Emulator(...).start()`` opens a pty and serves it on a thread; the returned path (the slave
tty, or a stable symlink to it when ``link_path`` is given, like ``/dev/serial/by-id``) is what
the driver opens with the real ``dynamixel_sdk``. Replies leave no faster than the configured
baud rate (10 bits per byte, request and reply both counted) plus the servo's Return Delay Time.

Faults: :meth:`inject_overheat`, :meth:`inject_overload`, ``no_reply`` (the line is dead: no
packet gets through), ``corrupt`` (replies with a wrong CRC/checksum), :meth:`unplug` /
:meth:`replug` (the pty disappears and a new one appears behind the same link).
"""

from __future__ import annotations

import logging
import os
import select
import threading
import time
import tty
from pathlib import Path

from dynamixel_sdk.protocol1_packet_handler import ERRBIT_OVERLOAD
from sofia_schemas.sim_world import WorldFile, world_path

from . import packets as pk
from .config import GripperConfig
from .control_table import Protocol
from .emulator_instructions import execute
from .emulator_servo import HW_OVERLOAD, Mx64Servo

log = logging.getLogger(__name__)


class Emulator:
    """One emulated MX-64 behind a pty. Thread-safe fault and object controls."""

    def __init__(
        self,
        protocol: Protocol = 2,
        baud: int = 1_000_000,
        dxl_id: int = 1,
        object_width_mm: float | None = None,
        config: GripperConfig | None = None,
        link_path: str | Path | None = None,
    ) -> None:
        self.protocol, self.baud, self.dxl_id = protocol, baud, dxl_id
        self.config = config or GripperConfig()
        self.link_path = Path(link_path) if link_path else None
        self.servo = Mx64Servo(protocol, dxl_id, position_ticks=float(self.config.open_ticks))
        self.lock = threading.Lock()
        self.no_reply = False
        self.corrupt = False
        self.cut = False  # status packets carry half their data (valid checksums)
        self.late_s = 0.0  # the next reply this late, seconds (then 0)
        self.packets = 0
        self._parser = pk.PacketParser(protocol)
        self._fds: tuple[int, int] | None = None
        self._slave_name = ""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.set_object(object_width_mm)
        # the simulated cell's shared world (SOFIA_SIM_WORLD): the fingers stop at the width of the
        # object between them, and close on nothing when there is none
        path = world_path()
        self.world = None if path is None else WorldFile(path)

    # --- lifecycle --------------------------------------------------------
    @property
    def path(self) -> str:
        return str(self.link_path) if self.link_path else self._slave_name

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        self._fds = (master, slave)
        self._slave_name = os.ttyname(slave)
        self._parser = pk.PacketParser(self.protocol)
        if self.link_path:
            tmp = self.link_path.with_name(self.link_path.name + ".new")
            tmp.unlink(missing_ok=True)
            tmp.symlink_to(self._slave_name)
            tmp.replace(self.link_path)

    def _close_pty(self) -> None:
        if self._fds:
            for fd in self._fds:
                os.close(fd)
            self._fds = None
        if self.link_path:
            self.link_path.unlink(missing_ok=True)

    def start(self) -> str:
        """Open the pty and serve it on a daemon thread; returns the tty path."""
        self._open_pty()
        self._thread = threading.Thread(target=self.serve, name="mx64-emulator", daemon=True)
        self._thread.start()
        log.info(
            "MX-64 emulator (protocol %d, id %d, %d baud) on %s",
            self.protocol,
            self.dxl_id,
            self.baud,
            self.path,
        )
        return self.path

    def stop(self) -> None:
        self._stop.set()
        if self._thread:
            self._thread.join(2.0)
        with self.lock:
            self._close_pty()

    def __enter__(self) -> Emulator:
        self.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self.stop()

    # --- faults and world -------------------------------------------------
    def set_object(self, width_mm: float | None) -> None:
        """Place an object of ``width_mm`` between the fingers (None: nothing)."""
        ticks = None if width_mm is None else float(self.config.kinematics().ticks(width_mm))
        with self.lock:
            self.servo.object_ticks = ticks

    def inject_overheat(self) -> None:
        with self.lock:
            self.servo.temperature_c = self.servo.get("temperature_limit") + 5.0

    def inject_overload(self) -> None:
        with self.lock:
            self.servo.hw_error |= HW_OVERLOAD if self.protocol == 2 else ERRBIT_OVERLOAD

    def clear_faults(self) -> None:
        """Cool down and drop the overload cause (the servo still needs a reboot to clear its error)."""
        with self.lock:
            self.servo.temperature_c = 40.0
            self.no_reply = self.corrupt = self.cut = False

    def unplug(self) -> None:
        with self.lock:
            self._close_pty()
        log.info("emulator unplugged")

    def replug(self) -> None:
        with self.lock:
            if self._fds is None:
                self._open_pty()
        log.info("emulator plugged in again on %s", self.path)

    def control(self, line: str) -> str:
        """One console command (``sofia gripper emulate`` reads them from stdin): ``object MM|none``,
        ``overheat``, ``overload``, ``noreply on|off``, ``corrupt on|off``, ``cut on|off`` (status
        packets with half their data, valid checksums), ``late MS`` (the next reply MS late),
        ``unplug``, ``replug``, ``clear``. Returns what was done, or what was wrong with the line."""
        word, *rest = line.split() or [""]
        arg = rest[0] if rest else ""
        if word == "object" and arg:
            self.set_object(None if arg == "none" else float(arg))
        elif word in ("noreply", "corrupt", "cut") and arg in ("on", "off"):
            setattr(self, {"noreply": "no_reply"}.get(word, word), arg == "on")
        elif word == "late" and arg.replace(".", "", 1).isdigit():
            self.late_s = float(arg) / 1000.0
        elif word in ("overheat", "overload", "unplug", "replug", "clear"):
            getattr(
                self,
                {"overheat": "inject_overheat", "overload": "inject_overload", "clear": "clear_faults"}.get(
                    word, word
                ),
            )()
        else:
            return f"unknown command {line.strip()!r}: object MM|none, overheat, overload, noreply on|off, corrupt on|off, cut on|off, late MS, unplug, replug, clear"
        return f"ok: {line.strip()}"

    def snapshot(self) -> dict[str, float]:
        """Motor state for tests: position (ticks), velocity, current (mA), temperature, torque."""
        with self.lock:
            s = self.servo
            s.advance(time.monotonic())
            return {
                "position": s.position, "velocity": s.velocity, "current_ma": s.current_ma,
                "temperature_c": s.temperature_c, "torque": float(s.get("torque_enable")),
                "watchdog": float(s.get("bus_watchdog")) if self.protocol == 2 else 0.0,
            }  # fmt: skip

    # --- serving ----------------------------------------------------------
    def serve(self) -> None:
        """Answer packets until :meth:`stop` (runs on the caller's thread)."""
        while not self._stop.is_set():
            if self.world is not None and self.world.poll() and self.world.state is not None:
                self.set_object(self.world.state.between_width_mm)
            fds = self._fds
            if fds is None:
                time.sleep(0.02)
                continue
            try:
                ready, _, _ = select.select([fds[0]], [], [], 0.05)
                data = os.read(fds[0], 4096) if ready else b""
            except OSError:  # closed under us (unplug) or no slave open yet
                time.sleep(0.005)
                continue
            if data:
                self._handle_bytes(data, time.monotonic())

    def _handle_bytes(self, data: bytes, t_arrival: float) -> None:
        for ins in self._parser.feed(data):
            with self.lock:
                if self.no_reply:
                    continue
                reply = self._dispatch(ins, t_arrival)
                fds = self._fds
                delay_s = self.servo.get("return_delay_time") * 2e-6 + self.late_s
                self.late_s = 0.0
            if reply and fds:
                if self.corrupt:
                    reply = reply[:-1] + bytes([reply[-1] ^ 0x5A])
                wire_s = (ins.size + len(reply)) * 10.0 / self.baud + delay_s
                time.sleep(max(0.0, t_arrival + wire_s - time.monotonic()))
                t_arrival = time.monotonic()
                try:
                    os.write(fds[0], reply)
                except OSError:
                    log.debug("reply lost: pty closed")

    def _dispatch(self, ins: pk.Instruction, now: float) -> bytes | None:
        s = self.servo
        mine = ins.dxl_id == self.dxl_id
        if not (mine or ins.dxl_id == pk.BROADCAST_ID):
            return None
        s.advance(now)
        s.t_last_packet = now
        self.packets += 1
        if not ins.valid:
            return self._status(pk.ERR_CRC if self.protocol == 2 else pk.ERRBIT1_CHECKSUM) if mine else None
        params, error, kind = execute(s, self.dxl_id, ins)
        if params is None:
            return None
        # "Status Return Level(68)": 0 answers PING only, 1 PING and READ (Sync/Bulk Read are
        # reads), 2 every instruction; a broadcast gets no status except PING and the group reads
        # (Protocol 2.0 "Ping": a broadcast ping is answered by every device).
        level = s.get("status_return_level")
        group = kind in {"sync_read", "bulk_read"}
        if kind == "ping" or (level >= 1 and (group or (mine and kind == "read"))) or (level >= 2 and mine):
            return self._status(error, params[: len(params) // 2] if self.cut else params)
        return None

    def _status(self, error: int, params: bytes = b"") -> bytes:
        err = error | self.servo.status_error()
        return pk.status_packet(self.protocol, self.dxl_id, err, params)
