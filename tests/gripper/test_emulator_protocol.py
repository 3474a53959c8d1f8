"""The emulator's Dynamixel protocol, exercised with the real dynamixel_sdk over the pty."""

from __future__ import annotations

import time

import serial
from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupBulkRead,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)
from sofia_gripper import Emulator
from sofia_gripper import packets as pk

from .conftest import BAUD, open_port

P2_ERR_ACCESS, P2_ERR_LIMIT = 7, 6


def test_ping_read_write_and_eeprom_lock_p2(emulator: Emulator, port: PortHandler) -> None:
    ph = PacketHandler(2.0)
    assert ph.ping(port, 1) == (311, COMM_SUCCESS, 0)
    assert ph.ping(port, 7)[1] == COMM_RX_TIMEOUT  # nobody with id 7
    assert ph.write1ByteTxRx(port, 1, 11, 5) == (COMM_SUCCESS, 0)  # operating mode, torque off: fine
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, 11, 3) == (COMM_SUCCESS, P2_ERR_ACCESS)  # EEPROM locked by torque
    assert ph.read1ByteTxRx(port, 1, 11) == (5, COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 1, 116, 2_000_000) == (COMM_SUCCESS, P2_ERR_LIMIT)  # beyond 256 turns
    assert ph.write1ByteTxRx(port, 1, 132, 1) == (COMM_SUCCESS, P2_ERR_ACCESS)  # read-only
    assert ph.write4ByteTxRx(port, 1, 116, 2200) == (COMM_SUCCESS, 0)
    time.sleep(0.5)
    assert abs(ph.read4ByteTxRx(port, 1, 132)[0] - 2200) <= 1


def test_sync_and_bulk_read_sync_write_reg_action_reboot_p2(emulator: Emulator, port: PortHandler) -> None:
    ph = PacketHandler(2.0)
    sw = GroupSyncWrite(port, ph, 64, 1)
    sw.addParam(1, [1])
    assert sw.txPacket() == COMM_SUCCESS
    time.sleep(0.01)
    sr = GroupSyncRead(port, ph, 64, 1)
    sr.addParam(1)
    assert sr.txRxPacket() == COMM_SUCCESS and sr.getData(1, 64, 1) == 1
    br = GroupBulkRead(port, ph)
    br.addParam(1, 0, 2)
    assert br.txRxPacket() == COMM_SUCCESS and br.getData(1, 0, 2) == 311
    assert ph.regWriteTxRx(port, 1, 116, 4, [0x00, 0x09, 0, 0])[0] == COMM_SUCCESS
    assert ph.read1ByteTxRx(port, 1, 69)[0] == 1  # registered
    assert ph.action(port, 1) == COMM_SUCCESS
    time.sleep(0.01)
    assert ph.read4ByteTxRx(port, 1, 116)[0] == 0x900
    assert ph.reboot(port, 1) == (COMM_SUCCESS, 0)
    assert ph.read1ByteTxRx(port, 1, 64)[0] == 0  # torque off after reboot
    assert ph.factoryReset(port, 1, 0x02) == (COMM_SUCCESS, 0)


def test_protocol1_ping_read_write_bulk(emulator_p1: Emulator) -> None:
    port = open_port(emulator_p1.path)
    try:
        ph = PacketHandler(1.0)
        assert ph.ping(port, 1) == (310, COMM_SUCCESS, 0)
        assert ph.write1ByteTxRx(port, 1, 24, 1) == (COMM_SUCCESS, 0)
        assert ph.write2ByteTxRx(port, 1, 30, 2000) == (COMM_SUCCESS, 0)
        assert ph.bulkReadTx(port, [2, 1, 30], 3) == COMM_SUCCESS
        data, result, _ = ph.readRx(port, 1, 2)
        assert result == COMM_SUCCESS and data[0] | (data[1] << 8) == 2000
        assert ph.write1ByteTxRx(port, 1, 99, 1)[1] == pk.ERRBIT1_RANGE  # nothing at 99
    finally:
        port.closePort()


def test_bad_crc_gets_a_crc_error_status(emulator: Emulator) -> None:
    packet = bytearray(pk.instruction_packet(2, 1, pk.INST_PING))
    packet[-1] ^= 0x01
    with serial.Serial(emulator.path, BAUD, timeout=0.5) as line:
        line.write(packet)
        reply = line.read(11)
    assert reply[:5] == b"\xff\xff\xfd\x00\x01" and reply[8] == pk.ERR_CRC


def test_reply_pacing_follows_the_baud_rate(emulator: Emulator) -> None:
    """A 100-byte read at 57600 baud cannot come back faster than the wire allows."""
    emulator.baud = 57600
    with serial.Serial(emulator.path, 57600, timeout=1.0) as line:
        request = pk.instruction_packet(2, 1, pk.INST_READ, bytes([0, 0, 100, 0]))
        t0 = time.monotonic()
        line.write(request)
        reply = line.read(111)
        elapsed = time.monotonic() - t0
    assert len(reply) == 111
    assert elapsed >= (len(request) + 111) * 10 / 57600


def test_fault_switches_no_reply_and_corrupt(emulator: Emulator, port: PortHandler) -> None:
    ph = PacketHandler(2.0)
    emulator.corrupt = True
    assert ph.ping(port, 1)[1] == COMM_RX_CORRUPT
    emulator.corrupt, emulator.no_reply = False, True
    assert ph.ping(port, 1)[1] == COMM_RX_TIMEOUT
    emulator.no_reply = False
    assert ph.ping(port, 1)[1] == COMM_SUCCESS
