"""One port for Foxglove clients of both subprotocol names, ``foxglove.sdk.v1`` and ``foxglove.websocket.v1``.

The Foxglove SDK's server accepts only ``foxglove.sdk.v1`` and answers HTTP 400 to clients that offer
only ``foxglove.websocket.v1`` (Lichtblick 1.21 and earlier, older Foxglove Studio, the ws-protocol
libraries). Foxglove gives both names to the same protocol (ws-protocol's ``docs/spec.md``, v1).
:class:`SubprotocolFront` listens on the public address in front of the SDK's server (on a loopback
port): it reads each client's HTTP upgrade request and, when the client offered only the older name,
names ``foxglove.sdk.v1`` in its ``Sec-WebSocket-Protocol`` header, passes the request on, and writes
the older name back into the server's ``101`` response. From then on it copies the bytes both ways
unchanged: WebSocket frames and ``Sec-WebSocket-Accept`` do not depend on the subprotocol's name.
"""

from __future__ import annotations

import logging
import socket
import socketserver
import threading

log = logging.getLogger("sofia.viz")
SDK_SUBPROTOCOL = "foxglove.sdk.v1"
LEGACY_SUBPROTOCOL = "foxglove.websocket.v1"
HEADER = b"sec-websocket-protocol"
MAX_HEAD_BYTES = 64 * 1024  # an HTTP upgrade request or response head
CHUNK_BYTES = 256 * 1024
HANDSHAKE_TIMEOUT_S = 10.0


def _read_head(sock: socket.socket) -> tuple[bytes, bytes]:
    """The HTTP head (through the blank line) and the bytes read past it; ``(b"", b"")`` when the
    peer closed first; ``ValueError`` when the head exceeds :data:`MAX_HEAD_BYTES`."""
    data = b""
    while b"\r\n\r\n" not in data:
        if len(data) > MAX_HEAD_BYTES:
            raise ValueError(f"HTTP head longer than {MAX_HEAD_BYTES} bytes")
        chunk = sock.recv(4096)
        if not chunk:
            return b"", b""
        data += chunk
    end = data.index(b"\r\n\r\n") + 4
    return data[:end], data[end:]


def _offered(head: bytes) -> list[str]:
    """The subprotocols named in a head's ``Sec-WebSocket-Protocol`` header(s), in order."""
    names: list[str] = []
    for line in head.split(b"\r\n")[1:]:
        name, sep, value = line.partition(b":")
        if sep and name.strip().lower() == HEADER:
            names += [v.strip() for v in value.decode("latin-1").split(",") if v.strip()]
    return names


def _with_subprotocol(head: bytes, subprotocol: str) -> bytes:
    """``head`` with its ``Sec-WebSocket-Protocol`` header(s) replaced by one naming ``subprotocol``."""
    lines = head[:-4].split(b"\r\n")
    kept = [line for line in lines if line.partition(b":")[0].strip().lower() != HEADER]
    return b"\r\n".join([*kept, b"Sec-WebSocket-Protocol: " + subprotocol.encode()]) + b"\r\n\r\n"


def legacy_only(head: bytes) -> bool:
    """True when an upgrade request offers ``foxglove.websocket.v1`` and not ``foxglove.sdk.v1``."""
    offered = _offered(head)
    return LEGACY_SUBPROTOCOL in offered and SDK_SUBPROTOCOL not in offered


def _pump(src: socket.socket, dst: socket.socket) -> None:
    """Copy ``src`` to ``dst`` until ``src`` ends, then end ``dst``'s sending side."""
    try:
        while chunk := src.recv(CHUNK_BYTES):
            dst.sendall(chunk)
    except OSError:
        pass  # either side closed
    finally:
        try:
            dst.shutdown(socket.SHUT_WR)
        except OSError:
            pass


class _Handler(socketserver.BaseRequestHandler):
    server: _Server

    def handle(self) -> None:
        client: socket.socket = self.request
        try:
            upstream = socket.create_connection(
                ("127.0.0.1", self.server.upstream_port), timeout=HANDSHAKE_TIMEOUT_S
            )
        except OSError as e:
            log.warning("Foxglove server on 127.0.0.1:%d not reachable: %s", self.server.upstream_port, e)
            return
        with upstream:
            client.settimeout(HANDSHAKE_TIMEOUT_S)  # a client that never sends its request is dropped
            try:
                head, rest = _read_head(client)
                if not head:
                    return
                legacy = legacy_only(head)
                upstream.sendall((_with_subprotocol(head, SDK_SUBPROTOCOL) if legacy else head) + rest)
                reply, rest = _read_head(upstream)
                if legacy and _offered(reply) == [SDK_SUBPROTOCOL]:
                    reply = _with_subprotocol(reply, LEGACY_SUBPROTOCOL)
                client.sendall(reply + rest)
            except (OSError, ValueError) as e:
                log.info("Foxglove handshake from %s failed: %s", self.client_address, e)
                return
            upstream.settimeout(None)
            client.settimeout(None)
            back = threading.Thread(target=_pump, args=(upstream, client), name="viz-ws-down", daemon=True)
            back.start()
            _pump(client, upstream)
            back.join()


class _Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], upstream_port: int) -> None:
        self.upstream_port = upstream_port
        self.address_family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        super().__init__(address, _Handler)


class SubprotocolFront:
    """Listens on ``host:port`` (0: a free port) for Foxglove clients of either subprotocol name and
    relays them to the SDK's server on ``127.0.0.1:upstream_port``; ``OSError`` when it cannot bind."""

    def __init__(self, host: str, port: int, upstream_port: int) -> None:
        self._server = _Server((host, port), upstream_port)
        self.port = int(self._server.server_address[1])
        self._thread = threading.Thread(target=self._server.serve_forever, name="viz-ws-front", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop accepting clients (connected ones end with the SDK's server)."""
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=2.0)
