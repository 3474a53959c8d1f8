"""A forged Zenoh HELLO must not make a service dial an endpoint it was not configured with.

A peer with multicast scouting keeps a UDP scouting socket bound to all interfaces; a HELLO sent to
it advertises locators the peer then connects to. SofIA's default bus has no scouting (and so no
such socket); the test forges HELLOs (to loopback only) advertising a TCP listener of its own to
every UDP socket the running detector holds and checks that it never connects, while a session
with Zenoh's own defaults does: the test can tell the difference."""

from __future__ import annotations

import json
import os
import socket
import time
from pathlib import Path

import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.client import ask
from sofia_schemas import Keys
from sofia_schemas.messages import ServiceStatus

from .conftest import Service

HELLO, FLAG_LOCATORS, VERSION, PEER = 0x02, 0x20, 0x09, 0x01


def _zint(n: int) -> bytes:
    out = bytearray()
    while True:
        byte, n = n & 0x7F, n >> 7
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


def forged_hello(locator: str) -> bytes:
    """A scouting HELLO of a made-up peer advertising ``locator`` (Zenoh 1.x wire format)."""
    zid = os.urandom(16)
    loc = locator.encode()
    return (
        bytes([HELLO | FLAG_LOCATORS, VERSION, PEER | (len(zid) - 1) << 4])
        + zid
        + _zint(1)
        + _zint(len(loc))
        + loc
    )


def udp_ports(pid: int) -> list[int]:
    """Local ports of the UDP sockets process ``pid`` holds (from /proc)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    ports = []
    for table in ("udp", "udp6"):
        for line in Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]:
            cols = line.split()
            if cols[9] in inodes:
                ports.append(int(cols[1].rsplit(":", 1)[1], 16))
    return ports


def dialled_after_forged_hello(pid: int, seconds: float = 4.0) -> bool:
    """Send forged HELLOs to every scouting socket of ``pid`` (on 127.0.0.1) advertising a TCP
    listener of this test; True when anything connects to it."""
    with socket.socket() as listener, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        listener.settimeout(0.25)
        hello = forged_hello(f"tcp/127.0.0.1:{listener.getsockname()[1]}")
        ports = [p for p in udp_ports(pid) if p != 7446]  # 7446: the multicast group's socket
        if not ports:  # no scouting socket: no HELLO can reach the process at all
            return False
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            for port in ports:
                udp.sendto(hello, ("127.0.0.1", port))
            try:
                listener.accept()[0].close()
                return True
            except TimeoutError:
                continue
    return False


def test_a_forged_hello_does_not_make_the_detector_dial_out(detector: Service, module_robot: str) -> None:
    assert udp_ports(detector.pid) == []  # no scouting at all
    assert not dialled_after_forged_hello(detector.pid)
    with zenoh.open(zenoh_config()) as session:  # the service still serves its real peers
        status = ask(session, Keys(module_robot).status("detector"), ServiceStatus, timeout=20)
    assert status.service == "detector"


def test_zenohs_own_defaults_would_dial_out() -> None:
    """The control: a peer with multicast scouting and TCP allowed connects to the forged locator."""
    conf = zenoh.Config()
    conf.insert_json5("listen/endpoints", json.dumps(["tcp/127.0.0.1:0"]))
    conf.insert_json5("scouting/multicast/interface", json.dumps("lo"))
    with zenoh.open(conf):
        assert udp_ports(os.getpid()) and dialled_after_forged_hello(os.getpid())
