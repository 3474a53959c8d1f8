"""Dynamixel packet framing, byte for byte, as the servo sees it (used by the emulator).

The instruction and error numbers, the Protocol 2.0 CRC and byte stuffing are the vendor SDK's
(``dynamixel_sdk``); this module frames whole packets and parses a byte stream into them.

Protocol 2.0: ``FF FF FD 00 ID LEN_L LEN_H INST PARAMS... CRC_L CRC_H``, LEN counts INST, PARAMS
and the CRC; CRC-16 (polynomial 0x8005, no reflection, init 0) over everything before the CRC;
``FF FF FD`` inside INST..PARAMS is stuffed as ``FF FF FD FD``. A status packet has INST 0x55
followed by an ERROR byte.

Protocol 1.0: ``FF FF ID LEN INST PARAMS... CHKSUM``, LEN = len(PARAMS) + 2, checksum is the
inverted low byte of the sum of ID..PARAMS. A status packet has the ERROR byte in place of INST.
"""

from __future__ import annotations

from dataclasses import dataclass

from dynamixel_sdk.protocol1_packet_handler import ERRBIT_CHECKSUM as ERRBIT1_CHECKSUM
from dynamixel_sdk.protocol1_packet_handler import ERRBIT_INSTRUCTION as ERRBIT1_INSTRUCTION
from dynamixel_sdk.protocol1_packet_handler import ERRBIT_RANGE as ERRBIT1_RANGE
from dynamixel_sdk.protocol2_packet_handler import ERRNUM_ACCESS as ERR_ACCESS
from dynamixel_sdk.protocol2_packet_handler import ERRNUM_CRC as ERR_CRC
from dynamixel_sdk.protocol2_packet_handler import ERRNUM_DATA_LENGTH as ERR_DATA_LENGTH
from dynamixel_sdk.protocol2_packet_handler import ERRNUM_DATA_LIMIT as ERR_DATA_LIMIT
from dynamixel_sdk.protocol2_packet_handler import ERRNUM_DATA_RANGE as ERR_DATA_RANGE
from dynamixel_sdk.protocol2_packet_handler import ERRNUM_INSTRUCTION as ERR_INSTRUCTION
from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler
from dynamixel_sdk.robotis_def import (
    BROADCAST_ID,
    INST_ACTION,
    INST_BULK_READ,
    INST_FACTORY_RESET,
    INST_PING,
    INST_READ,
    INST_REBOOT,
    INST_REG_WRITE,
    INST_STATUS,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    INST_WRITE,
)

__all__ = [
    "BROADCAST_ID", "ERRBIT1_CHECKSUM", "ERRBIT1_INSTRUCTION", "ERRBIT1_RANGE", "ERR_ACCESS", "ERR_CRC",
    "ERR_DATA_LENGTH", "ERR_DATA_LIMIT", "ERR_DATA_RANGE", "ERR_INSTRUCTION", "INST_ACTION", "INST_BULK_READ",
    "INST_FACTORY_RESET", "INST_PING", "INST_READ", "INST_REBOOT", "INST_REG_WRITE", "INST_STATUS",
    "INST_SYNC_READ", "INST_SYNC_WRITE", "INST_WRITE", "Instruction", "PacketParser", "instruction_packet",
    "status_packet",
]  # fmt: skip
_SDK2 = Protocol2PacketHandler()  # its CRC-16 and byte stuffing are those of the servo's firmware


def _crc16(data: bytes | list[int]) -> int:
    return int(_SDK2.updateCRC(0, data, len(data)))


def _checksum1(data: bytes) -> int:
    """Protocol 1.0 checksum of ID..PARAMS."""
    return (~sum(data)) & 0xFF


def instruction_packet(protocol: int, dxl_id: int, inst: int, params: bytes = b"") -> bytes:
    """A complete packet with ``inst`` (or, for a Protocol 1.0 status packet, the error byte)."""
    if protocol == 1:
        body = bytes([dxl_id, len(params) + 2, inst]) + params
        return b"\xff\xff" + body + bytes([_checksum1(body)])
    length = len(params) + 3
    packet = _SDK2.addStuffing(
        [0xFF, 0xFF, 0xFD, 0x00, dxl_id, length & 0xFF, length >> 8, inst, *params, 0, 0]
    )
    crc = _crc16(packet[:-2])
    return bytes(packet[:-2]) + bytes([crc & 0xFF, crc >> 8])


def status_packet(protocol: int, dxl_id: int, error: int, params: bytes = b"") -> bytes:
    """A complete status packet of ``protocol`` with ``error`` and ``params``."""
    if protocol == 1:
        return instruction_packet(1, dxl_id, error, params)
    return instruction_packet(2, dxl_id, INST_STATUS, bytes([error]) + params)


@dataclass(frozen=True)
class Instruction:
    """A parsed instruction packet; ``valid`` is False when its CRC/checksum did not match."""

    dxl_id: int
    inst: int
    params: bytes
    valid: bool
    size: int  # bytes on the wire


class PacketParser:
    """Incremental parser: feed bytes as they arrive, get complete instruction packets out."""

    def __init__(self, protocol: int) -> None:
        self.protocol = protocol
        self.buf = bytearray()

    def feed(self, data: bytes) -> list[Instruction]:
        self.buf += data
        out: list[Instruction] = []
        while True:
            packet = self._next()
            if packet is None:
                return out
            out.append(packet)

    def _next(self) -> Instruction | None:
        head = b"\xff\xff\xfd\x00" if self.protocol == 2 else b"\xff\xff"
        start = self.buf.find(head)
        if start < 0:
            del self.buf[: max(0, len(self.buf) - len(head) + 1)]
            return None
        del self.buf[:start]
        return self._next2() if self.protocol == 2 else self._next1()

    def _next2(self) -> Instruction | None:
        if len(self.buf) < 7:
            return None
        length = self.buf[5] | (self.buf[6] << 8)
        total = 7 + length
        if length < 3 or length > 1024:
            del self.buf[0]
            return None if len(self.buf) < 7 else self._next()
        if len(self.buf) < total:
            return None
        raw = bytes(self.buf[:total])
        del self.buf[:total]
        valid = _crc16(raw[:-2]) == (raw[-2] | (raw[-1] << 8))
        packet = _SDK2.removeStuffing(list(raw))
        body = bytes(packet[7 : 5 + (packet[5] | (packet[6] << 8))])  # INST..PARAMS
        return Instruction(raw[4], body[0], body[1:], valid, total)

    def _next1(self) -> Instruction | None:
        if len(self.buf) < 4:
            return None
        if self.buf[2] == 0xFF:  # a third FF: the header starts one byte later
            del self.buf[0]
            return self._next()
        total = 4 + self.buf[3]
        if len(self.buf) < total:
            return None
        raw = bytes(self.buf[:total])
        del self.buf[:total]
        valid = _checksum1(raw[2:-1]) == raw[-1]
        return Instruction(raw[2], raw[4], raw[5:-1], valid, total)
