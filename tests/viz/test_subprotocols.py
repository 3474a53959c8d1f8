"""The handshake rewrite of the viz's front: which upgrade requests are renamed, and how."""

from __future__ import annotations

from sofia_viz.subprotocols import (
    LEGACY_SUBPROTOCOL,
    SDK_SUBPROTOCOL,
    _offered,
    _with_subprotocol,
    legacy_only,
)


def _request(*headers: str) -> bytes:
    lines = ["GET / HTTP/1.1", "Host: 127.0.0.1:8765", "Upgrade: websocket", "Connection: Upgrade", *headers]
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def test_only_requests_offering_the_older_name_alone_are_renamed() -> None:
    assert legacy_only(_request("Sec-WebSocket-Protocol: foxglove.websocket.v1"))
    assert legacy_only(
        _request("sec-websocket-protocol: other.v1, foxglove.websocket.v1")
    )  # any case, listed
    assert not legacy_only(_request("Sec-WebSocket-Protocol: foxglove.websocket.v1, foxglove.sdk.v1"))
    assert not legacy_only(_request("Sec-WebSocket-Protocol: foxglove.websocket.v1", "Sec-WebSocket-Protocol: foxglove.sdk.v1"))  # fmt: skip
    assert not legacy_only(_request("Sec-WebSocket-Protocol: foxglove.sdk.v1"))
    assert not legacy_only(_request())  # no subprotocol: the SDK's server answers (400)


def test_rename_replaces_every_subprotocol_header_and_keeps_the_rest() -> None:
    head = _request("Sec-WebSocket-Protocol: other.v1", "Sec-WebSocket-Key: abc==", "sec-websocket-protocol: foxglove.websocket.v1")  # fmt: skip
    renamed = _with_subprotocol(head, SDK_SUBPROTOCOL)
    assert _offered(renamed) == [SDK_SUBPROTOCOL]
    assert b"Sec-WebSocket-Key: abc==\r\n" in renamed and renamed.startswith(b"GET / HTTP/1.1\r\n")
    assert renamed.endswith(b"\r\n\r\n") and renamed.count(b"\r\n\r\n") == 1
    assert _offered(_with_subprotocol(renamed, LEGACY_SUBPROTOCOL)) == [LEGACY_SUBPROTOCOL]
