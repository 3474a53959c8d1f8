"""Packet framing against the e-Manual's examples and the real dynamixel_sdk's own framing."""

from __future__ import annotations

import pytest
from dynamixel_sdk import Protocol2PacketHandler
from hypothesis import given
from hypothesis import strategies as st
from sofia_gripper import packets as pk


def test_crc16_matches_the_emanual_ping_example() -> None:
    # e-Manual Protocol 2.0, Ping example: FF FF FD 00 01 03 00 01 19 4E
    packet = pk.instruction_packet(2, 1, pk.INST_PING)
    assert packet == bytes.fromhex("FFFFFD0001030001194E")


def test_protocol1_checksum_matches_the_emanual_ping_example() -> None:
    # e-Manual Protocol 1.0, Ping ID 1: FF FF 01 02 01 FB
    assert pk.instruction_packet(1, 1, pk.INST_PING) == bytes.fromhex("FFFF010201FB")


@pytest.mark.parametrize("protocol", [1, 2])
@given(params=st.binary(max_size=40))
def test_framing_round_trips_and_leaves_no_header_in_the_body(protocol: int, params: bytes) -> None:
    packet = pk.instruction_packet(protocol, 1, pk.INST_WRITE, params)
    if protocol == 2:
        assert packet.count(b"\xff\xff\xfd") - packet.count(b"\xff\xff\xfd\xfd") == 1
    (got,) = pk.PacketParser(protocol).feed(packet)
    assert (got.dxl_id, got.inst, got.params, got.valid, got.size) == (
        1,
        pk.INST_WRITE,
        params,
        True,
        len(packet),
    )


@pytest.mark.parametrize("protocol", [1, 2])
def test_parser_reassembles_packets_split_anywhere_and_flags_bad_crc(protocol: int) -> None:
    good = pk.instruction_packet(protocol, 1, pk.INST_WRITE, bytes([116, 0, 0xFF, 0xFF, 0xFD, 0]))
    bad = bytearray(good)
    bad[-1] ^= 0xFF
    stream = b"\x00\x13" + good + bytes(bad) + good
    for cut in range(1, len(stream)):
        parser = pk.PacketParser(protocol)
        got = parser.feed(stream[:cut]) + parser.feed(stream[cut:])
        assert [p.valid for p in got] == [True, False, True], cut
        assert got[0].params == bytes([116, 0, 0xFF, 0xFF, 0xFD, 0])
        assert got[0].inst == pk.INST_WRITE and got[0].dxl_id == 1


def test_status_packet_destuffs_with_the_sdk() -> None:
    params = bytes([0xFF, 0xFF, 0xFD, 0x01])
    status = pk.status_packet(2, 1, 0, params)
    assert len(status) == 7 + 2 + len(params) + 1 + 2  # one stuffing byte
    sdk = Protocol2PacketHandler()
    assert sdk.updateCRC(0, status[:-2], len(status) - 2) == status[-2] | (status[-1] << 8)
    rx = sdk.removeStuffing(list(status))
    length = rx[5] | (rx[6] << 8)
    assert bytes(rx[7 : 7 + length - 2]) == bytes([pk.INST_STATUS, 0]) + params
