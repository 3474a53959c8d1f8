"""Dynamixel packet framing, byte for byte, as the servo sees it (used by the emulator).

Protocol 2.0: ``FF FF FD 00 ID LEN_L LEN_H INST PARAMS... CRC_L CRC_H``, LEN counts INST, PARAMS
and the CRC; CRC-16 (polynomial 0x8005, no reflection, init 0) over everything before the CRC;
``FF FF FD`` inside INST..PARAMS is stuffed as ``FF FF FD FD``. A status packet has INST 0x55
followed by an ERROR byte.

Protocol 1.0: ``FF FF ID LEN INST PARAMS... CHKSUM``, LEN = len(PARAMS) + 2, checksum is the
inverted low byte of the sum of ID..PARAMS. A status packet has the ERROR byte in place of INST.
"""

from __future__ import annotations

from dataclasses import dataclass

INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_REG_WRITE = 0x04
INST_ACTION = 0x05
INST_FACTORY_RESET = 0x06
INST_REBOOT = 0x08
INST_STATUS = 0x55
INST_SYNC_READ = 0x82
INST_SYNC_WRITE = 0x83
INST_BULK_READ = 0x92
BROADCAST_ID = 0xFE

# Protocol 2.0 status error numbers.
ERR_RESULT_FAIL = 1
ERR_INSTRUCTION = 2
ERR_CRC = 3
ERR_DATA_RANGE = 4
ERR_DATA_LENGTH = 5
ERR_DATA_LIMIT = 6
ERR_ACCESS = 7
# Protocol 1.0 status error bits.
ERRBIT1_RANGE = 1 << 3
ERRBIT1_CHECKSUM = 1 << 4
ERRBIT1_INSTRUCTION = 1 << 6


def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray) -> int:
    """Dynamixel Protocol 2.0 CRC-16 of ``data``."""
    crc = 0
    for b in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ b) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Insert 0xFD after every ``FF FF FD`` in ``body`` (INST..PARAMS, preceded by the header)."""
    out = bytearray(b"\xff\xff\xfd\x00")  # the header primes the FF FF detection
    for b in body:
        out.append(b)
        if b == 0xFD and out[-2] == 0xFF and out[-3] == 0xFF:
            out.append(0xFD)
    return bytes(out[4:])


def unstuff(body: bytes) -> bytes:
    """Remove the stuffing byte of every ``FF FF FD FD`` in ``body``."""
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if body[i] == 0xFD and i + 1 < len(body) and body[i + 1] == 0xFD and out[-3:-1] == b"\xff\xff":
            i += 1
        i += 1
    return bytes(out)


def checksum1(data: bytes | bytearray) -> int:
    """Protocol 1.0 checksum of ID..PARAMS."""
    return (~sum(data)) & 0xFF


def status_packet(protocol: int, dxl_id: int, error: int, params: bytes = b"") -> bytes:
    """A complete status packet of ``protocol`` with ``error`` and ``params``."""
    if protocol == 1:
        body = bytes([dxl_id, len(params) + 2, error]) + params
        return b"\xff\xff" + body + bytes([checksum1(body)])
    payload = stuff(bytes([INST_STATUS, error]) + params)
    length = len(payload) + 2
    head = bytes([0xFF, 0xFF, 0xFD, 0x00, dxl_id, length & 0xFF, length >> 8])
    crc = crc16(head + payload)
    return head + payload + bytes([crc & 0xFF, crc >> 8])


def instruction_packet(protocol: int, dxl_id: int, inst: int, params: bytes = b"") -> bytes:
    """A complete instruction packet (the host side; for sizes and tests)."""
    if protocol == 1:
        body = bytes([dxl_id, len(params) + 2, inst]) + params
        return b"\xff\xff" + body + bytes([checksum1(body)])
    payload = stuff(bytes([inst]) + params)
    length = len(payload) + 2
    head = bytes([0xFF, 0xFF, 0xFD, 0x00, dxl_id, length & 0xFF, length >> 8])
    crc = crc16(head + payload)
    return head + payload + bytes([crc & 0xFF, crc >> 8])


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
        valid = crc16(raw[:-2]) == (raw[-2] | (raw[-1] << 8))
        body = unstuff(raw[7:-2])
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
        valid = checksum1(raw[2:-1]) == raw[-1]
        return Instruction(raw[2], raw[4], raw[5:-1], valid, total)
