"""The serial bus to one MX-64 through the real ``dynamixel_sdk`` (PortHandler / PacketHandler).

Every exchange checks the communication result and the status packet's error byte and raises a
:class:`~sofia_gripper.errors.BusError` or :class:`~sofia_gripper.errors.ServoRefused` naming
what failed. The state block is read with one Sync Read (Protocol 2.0) or Bulk Read (Protocol
1.0) per call. Hardware-error bits of the status error byte (P2 alert bit, P1 overheat /
overload / voltage) are not errors of the exchange: they are kept in ``last_status_error``.

Reads take the status packet themselves (``rxPacket``) and check its parameter count against the
bytes asked for: Protocol 2.0 status packets carry no request id, so a late reply to an earlier
request (a host stalled past its timeout) or a cut packet would otherwise decode as zeros. Such a
reply is a :class:`~sofia_gripper.errors.CommFailed` and the line's buffered input is dropped.
"""

from __future__ import annotations

import termios
import threading
from collections.abc import Callable
from typing import Any

import serial
from dynamixel_sdk import COMM_SUCCESS, DXL_MAKEWORD, PacketHandler, PortHandler
from dynamixel_sdk import protocol1_packet_handler as sdk1
from dynamixel_sdk import protocol2_packet_handler as sdk2

from .control_table import ALERT_BIT_P2, HW_ERROR_MASK_P1, STATE_BLOCK, Protocol, decode_int, fields
from .errors import CommFailed, LineLost, ServoRefused


class MarginPort(PortHandler):
    """dynamixel_sdk's port with ``margin_ms`` added to every status-packet timeout (the SDK's
    allows for the adapter's 16 ms latency timer, not for a servo process on a loaded host)."""

    margin_ms = 0.0

    def setPacketTimeout(self, packet_length: int) -> None:
        super().setPacketTimeout(packet_length)
        self.packet_timeout += self.margin_ms

    def setPacketTimeoutMillis(self, msec: float) -> None:
        super().setPacketTimeoutMillis(msec + self.margin_ms)


class DxlBus:
    """One servo ``dxl_id`` on ``port`` at ``baud``, ``protocol`` 1 or 2. Thread-safe.
    ``timeout_margin_ms`` lengthens the wait for each status packet (see :class:`MarginPort`)."""

    def __init__(
        self, port: str, baud: int, protocol: Protocol, dxl_id: int, timeout_margin_ms: float = 0.0
    ) -> None:
        self.port_name, self.baud, self.protocol, self.dxl_id = port, baud, protocol, dxl_id
        self.timeout_margin_ms = timeout_margin_ms
        self.table = fields(protocol)
        self.ph = PacketHandler(float(protocol))
        self.port: PortHandler | None = None
        self.lock = threading.RLock()
        self.last_status_error = 0
        self.stale_replies = 0  # status packets of another size dropped (late replies to earlier requests)

    # --- line -------------------------------------------------------------
    def open(self) -> None:
        with self.lock:
            self.close()
            port = MarginPort(self.port_name)
            port.margin_ms = self.timeout_margin_ms
            try:
                if not port.setBaudRate(self.baud):
                    raise CommFailed(f"open {self.port_name!r}", f"baud rate {self.baud} not supported")
            except (serial.SerialException, OSError) as e:
                raise LineLost(self.port_name, e) from e
            self.port = port

    def close(self) -> None:
        with self.lock:
            if self.port is not None and self.port.is_open:
                try:
                    self.port.closePort()
                except (serial.SerialException, OSError):
                    pass
            self.port = None

    def _call(self, what: str, fn: Callable[..., Any], *args: Any) -> Any:
        with self.lock:
            if self.port is None:
                raise LineLost(self.port_name, "port not open")
            try:
                return fn(self.port, *args)
            except (serial.SerialException, OSError, TypeError, termios.error) as e:
                # TypeError: pyserial's read on a closed fd; the SDK leaves the port marked busy
                self.port.is_using = False
                raise LineLost(self.port_name, f"{what}: {e}") from e

    def _check(self, what: str, result: int, error: int) -> None:
        if result != COMM_SUCCESS:
            self._drop_stale_input()
            raise CommFailed(what, self.ph.getTxRxResult(result))
        hw = ALERT_BIT_P2 if self.protocol == 2 else HW_ERROR_MASK_P1
        self.last_status_error = error & hw
        if error & ~hw:
            raise ServoRefused(what, self.ph.getRxPacketError(error & ~hw), error & ~hw)

    def _drop_stale_input(self) -> None:
        """After a failed exchange, a late status packet may still arrive: drop what is buffered so
        the next exchange does not read it as its own reply (e.g. after the host stalled)."""
        with self.lock:
            if self.port is not None and self.port.is_open:
                try:
                    self.port.clearPort()
                except (serial.SerialException, OSError, termios.error):
                    pass

    # --- exchanges --------------------------------------------------------
    def ping(self) -> int:
        """The servo's model number."""
        model, result, error = self._call("ping", self.ph.ping, self.dxl_id)
        self._check(f"ping id {self.dxl_id}", result, error)
        return int(model)

    def _status(self, port: PortHandler, what: str, length: int) -> tuple[list[int], int, int]:
        """The servo's status packet of a read of ``length`` bytes: (data, result, error), as the
        SDK's ``readRx`` but with the packet's parameter count checked. Protocol 2.0 replies carry no
        request id, so a packet of another size is a late reply to an earlier request (the host gave
        up on it) or a cut one: it is dropped, counted in ``stale_replies``, and the read waits for
        its own reply within its timeout; when none comes, :class:`CommFailed` names the dropped one."""
        p2 = self.protocol == 2
        id_at, error_at = (sdk2.PKT_ID, sdk2.PKT_ERROR) if p2 else (sdk1.PKT_ID, sdk1.PKT_ERROR)
        dropped = -1
        while True:
            packet, result = self.ph.rxPacket(port, False) if p2 else self.ph.rxPacket(port)
            if result != COMM_SUCCESS:
                if dropped < 0:
                    return [], result, 0
                self._drop_stale_input()
                raise CommFailed(
                    what,
                    f"status packet with {dropped} data bytes, expected {length}: a stale or cut reply, dropped",
                )
            if packet[id_at] != self.dxl_id:
                continue
            if p2:  # LENGTH counts INST, ERROR, the data and the CRC
                n_data = DXL_MAKEWORD(packet[sdk2.PKT_LENGTH_L], packet[sdk2.PKT_LENGTH_H]) - 4
            else:  # LENGTH counts ERROR, the data and the checksum
                n_data = packet[sdk1.PKT_LENGTH] - 2
            if n_data == length:
                return list(packet[error_at + 1 : error_at + 1 + length]), result, packet[error_at]
            dropped = n_data
            self.stale_replies += 1

    def read(self, name: str) -> int:
        f = self.table[name]
        what = f"read {name} (address {f.address})"

        def exchange(port: PortHandler) -> tuple[list[int], int, int]:
            result = self.ph.readTx(port, self.dxl_id, f.address, f.size)
            if result != COMM_SUCCESS:
                port.is_using = False
                return [], result, 0
            return self._status(port, what, f.size)

        data, result, error = self._call(f"read {name}", exchange)
        self._check(what, result, error)
        return decode_int(data, 0, f)

    def write(self, name: str, value: int) -> None:
        f = self.table[name]
        raw = int(value) % (1 << (8 * f.size))
        fn = {1: self.ph.write1ByteTxRx, 2: self.ph.write2ByteTxRx, 4: self.ph.write4ByteTxRx}[f.size]
        result, error = self._call(f"write {name}", fn, self.dxl_id, f.address, raw)
        self._check(f"write {name}={value} (address {f.address})", result, error)

    def read_state(self) -> tuple[bytes, int]:
        """The state block (Moving..Present Temperature, P2; Present Position..Current, P1) and the
        status error byte, in one Sync Read (P2) or Bulk Read (P1)."""
        start, length = STATE_BLOCK[self.protocol]

        def exchange(port: PortHandler) -> tuple[list[int], int, int]:
            if self.protocol == 2:
                result = self.ph.syncReadTx(port, start, length, [self.dxl_id], 1, False)
            else:
                result = self.ph.bulkReadTx(port, [length, self.dxl_id, start], 3)
            if result != COMM_SUCCESS:
                port.is_using = False
                return [], result, 0
            return self._status(port, "state read", length)

        data, result, error = self._call("state read", exchange)
        self._check("state read", result, error)
        return bytes(data), error

    def reboot(self) -> None:
        if self.protocol == 1:
            raise CommFailed(
                "reboot", "Protocol 1.0 MX-64 firmware has no Reboot instruction; send torque on to re-arm"
            )
        result, error = self._call("reboot", self.ph.reboot, self.dxl_id)
        self._check("reboot", result, error & ~ALERT_BIT_P2)
