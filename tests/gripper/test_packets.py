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


@given(st.binary(max_size=64))
def test_crc16_equals_the_sdk_crc(data: bytes) -> None:
    assert pk.crc16(data) == Protocol2PacketHandler().updateCRC(0, list(data), len(data))


@given(st.binary(max_size=40))
def test_stuffing_round_trips_and_leaves_no_header_in_the_body(params: bytes) -> None:
    body = bytes([pk.INST_WRITE]) + params
    stuffed = pk.stuff(body)
    assert pk.unstuff(stuffed) == body
    framed = b"\xff\xff\xfd\x00" + stuffed
    assert framed.count(b"\xff\xff\xfd") - framed.count(b"\xff\xff\xfd\xfd") == 1


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
    assert pk.crc16(status[:-2]) == status[-2] | (status[-1] << 8)
    rx = Protocol2PacketHandler().removeStuffing(list(status))
    length = rx[5] | (rx[6] << 8)
    assert bytes(rx[7 : 7 + length - 2]) == bytes([pk.INST_STATUS, 0]) + params
