"""The instructions the emulated MX-64 understands, for Protocol 2.0 and 1.0 parameter layouts.

:func:`execute` returns ``(params, error, kind)``: the status packet parameters (None: no status
packet), the status error, and the instruction kind (which decides, with Status Return Level,
whether a status packet is sent).
"""

from __future__ import annotations

from . import packets as pk
from .emulator_servo import Mx64Servo

Result = tuple[bytes | None, int, str]


def _u16(b: bytes, i: int) -> int:
    return int.from_bytes(b[i : i + 2], "little")


def execute(s: Mx64Servo, dxl_id: int, ins: pk.Instruction) -> Result:
    """Run ``ins`` on servo ``s``, which answers to ``dxl_id`` (the caller holds its lock)."""
    p2 = s.protocol == 2
    p = ins.params
    bad_len = pk.ERR_DATA_LENGTH if p2 else pk.ERRBIT1_RANGE
    if ins.inst == pk.INST_PING:
        if ins.dxl_id == pk.BROADCAST_ID and not p2:
            return None, 0, "ping"
        info = s.read(0, 2) + bytes([s.get("firmware_version")]) if p2 else b""
        return info, 0, "ping"
    if ins.inst == pk.INST_READ:
        if ins.dxl_id == pk.BROADCAST_ID:
            return None, 0, "read"
        need = 4 if p2 else 2
        if len(p) != need:
            return b"", bad_len, "read"
        addr, length = (_u16(p, 0), _u16(p, 2)) if p2 else (p[0], p[1])
        if addr + length > len(s.mem):
            return b"", pk.ERR_ACCESS if p2 else pk.ERRBIT1_RANGE, "read"
        return s.read(addr, length), 0, "read"
    if ins.inst in (pk.INST_WRITE, pk.INST_REG_WRITE):
        hdr = 2 if p2 else 1
        if len(p) <= hdr:
            return b"", bad_len, "write"
        addr = _u16(p, 0) if p2 else p[0]
        if ins.inst == pk.INST_REG_WRITE:
            s.registered = (addr, bytes(p[hdr:]))
            s.set("registered_instruction", 1)
            return b"", 0, "write"
        return b"", s.write(addr, bytes(p[hdr:])), "write"
    if ins.inst == pk.INST_ACTION:
        if s.registered is None:
            return b"", pk.ERR_INSTRUCTION if p2 else pk.ERRBIT1_INSTRUCTION, "write"
        addr, data = s.registered
        s.registered = None
        s.set("registered_instruction", 0)
        return b"", s.write(addr, data), "write"
    if ins.inst == pk.INST_REBOOT and p2:
        s.reboot()
        return b"", 0, "write"
    if ins.inst == pk.INST_FACTORY_RESET:
        if s.get("torque_enable") and p2:
            return b"", pk.ERR_ACCESS, "write"
        option = p[0] if (p2 and p) else 0xFF
        s.factory_reset(1 if option == 0xFF else dxl_id)
        return b"", 0, "write"
    if ins.inst == pk.INST_SYNC_WRITE:
        return _sync_write(s, dxl_id, p)
    if ins.inst == pk.INST_SYNC_READ and p2:
        if len(p) < 5 or dxl_id not in p[4:]:
            return None, 0, "sync_read"
        addr, length = _u16(p, 0), _u16(p, 2)
        return s.read(addr, length), 0, "sync_read"
    if ins.inst == pk.INST_BULK_READ:
        return _bulk_read(s, dxl_id, p)
    return b"", pk.ERR_INSTRUCTION if p2 else pk.ERRBIT1_INSTRUCTION, "write"


def _sync_write(s: Mx64Servo, dxl_id: int, p: bytes) -> Result:
    p2 = s.protocol == 2
    hdr = 4 if p2 else 2
    if len(p) < hdr:
        return None, 0, "sync_write"
    addr, length = (_u16(p, 0), _u16(p, 2)) if p2 else (p[0], p[1])
    for i in range(hdr, len(p) - length, length + 1):
        if p[i] == dxl_id:
            s.write(addr, bytes(p[i + 1 : i + 1 + length]))
    return None, 0, "sync_write"


def _bulk_read(s: Mx64Servo, dxl_id: int, p: bytes) -> Result:
    if s.protocol == 2:  # [id, addr_l, addr_h, len_l, len_h] * n
        for i in range(0, len(p) - 4, 5):
            if p[i] == dxl_id:
                return s.read(_u16(p, i + 1), _u16(p, i + 3)), 0, "bulk_read"
        return None, 0, "bulk_read"
    for i in range(1, len(p) - 2, 3):  # 0x00, then [len, id, addr] * n
        if p[i + 1] == dxl_id:
            return s.read(p[i + 2], p[i]), 0, "bulk_read"
    return None, 0, "bulk_read"
