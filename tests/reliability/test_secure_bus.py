"""The shipped TLS recipe works, and only it: the secure router (docker/zenoh/router-secure.json5)
serves the shipped client config (docker/zenoh/client-secure.json5) with the right password, and
refuses a wrong or missing password, a certificate of another CA, no certificate and plain TCP.
Then its access control: only the calibrator's identity publishes calibration results, only the
arm and operator identities command the gripper. Real sessions, a real router, loopback only."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import pytest
import zenoh

from .conftest import Pki, SecureRouter

KEY = "sofia/tsec/detector/detections"


def _served(router: SecureRouter, pki: Pki, user: str = "detector") -> None:
    """Two clients through the router: a put of the detector reaches the subscriber of a tool."""
    got = threading.Event()
    with zenoh.open(router.client_config("sofia", pki.passwords["sofia"])) as sub_session:
        sub_session.declare_subscriber(KEY, lambda s: got.set())
        with zenoh.open(router.client_config(user, pki.passwords[user])) as pub_session:
            pub = pub_session.declare_publisher(KEY)
            deadline = time.monotonic() + 10
            while not got.is_set() and time.monotonic() < deadline:
                pub.put(b"{}")
                got.wait(0.2)
    assert got.is_set(), "the right password and certificate were not served"


def test_right_password_and_certificate_are_served(secure_router: SecureRouter, pki: Pki) -> None:
    _served(secure_router, pki)


def _refused(conf: zenoh.Config) -> None:
    with pytest.raises(zenoh.ZError):
        session = zenoh.open(conf)
        session.close()  # only reached when wrongly served


def test_wrong_password_refused(secure_router: SecureRouter) -> None:
    _refused(secure_router.client_config("sofia", "not-the-password"))


def test_no_password_refused(secure_router: SecureRouter) -> None:
    _refused(secure_router.client_config(None))


def test_unknown_user_refused(secure_router: SecureRouter, pki: Pki) -> None:
    _refused(secure_router.client_config("mallory", pki.passwords["sofia"]))


def test_certificate_of_another_ca_refused(secure_router: SecureRouter, pki: Pki) -> None:
    other = pki.dir / "other-client"
    conf = secure_router.client_config("sofia", pki.passwords["sofia"],
                                       connect_certificate=str(other / "cert.pem"),
                                       connect_private_key=str(other / "key.pem"))  # fmt: skip
    _refused(conf)


def test_no_client_certificate_refused(secure_router: SecureRouter, pki: Pki) -> None:
    conf = secure_router.client_config("sofia", pki.passwords["sofia"], connect_certificate=None,
                                       connect_private_key=None, enable_mtls=False)  # fmt: skip
    _refused(conf)


def test_router_of_another_ca_not_trusted(secure_router: SecureRouter, pki: Pki) -> None:
    """The client checks the router too: with another CA as root it does not connect."""
    conf = secure_router.client_config("sofia", pki.passwords["sofia"],
                                       root_ca_certificate=str(pki.dir / "other-ca.pem"))  # fmt: skip
    _refused(conf)


def test_plain_tcp_refused(secure_router: SecureRouter, pki: Pki) -> None:
    conf = secure_router.client_config("sofia", pki.passwords["sofia"])
    conf.insert_json5("connect/endpoints", f'["tcp/127.0.0.1:{secure_router.port}"]')
    conf.insert_json5("transport/link/protocols", '["tcp"]')
    _refused(conf)


def _received(router: SecureRouter, pki: Pki, publisher: str, key: str) -> bool:
    """Whether a put on ``key`` by ``publisher`` reaches a subscriber (the detector's identity)."""
    got = threading.Event()
    with zenoh.open(router.client_config("detector", pki.passwords["detector"])) as sub_session:
        sub_session.declare_subscriber(key, lambda s: got.set())
        with zenoh.open(router.client_config(publisher, pki.passwords[publisher])) as pub_session:
            pub = pub_session.declare_publisher(key)
            for _ in range(15):  # 3 s: discovery through the router takes well under that
                pub.put(b'{"forged": true}')
                if got.wait(0.2):
                    break
    return got.is_set()


@pytest.mark.parametrize("user", ["detector", "sofia", "arm"])
def test_only_the_calibrator_publishes_results(secure_router: SecureRouter, pki: Pki, user: str) -> None:
    key = "sofia/tsec/calibrator/result"
    assert not _received(secure_router, pki, user, key), f"{user} published a calibration result"
    assert _received(secure_router, pki, "calibrator", key)


def _gripper_replies(router: SecureRouter, pki: Pki, sender: str, forger: str | None = None) -> list[bytes]:
    """Replies to a gripper command sent by ``sender``, with a stand-in gripper (the gripper's
    identity) answering ``ok``, and maybe a forged answerer of identity ``forger``."""
    key = "sofia/tsec/gripper/command"
    sessions = [zenoh.open(router.client_config("gripper", pki.passwords["gripper"]))]
    answer: Callable[[bytes], Callable[[zenoh.Query], None]] = lambda text: lambda q: q.reply(key, text)  # noqa: E731
    try:
        sessions[0].declare_queryable(key, answer(b"ok"))
        if forger:
            sessions.append(zenoh.open(router.client_config(forger, pki.passwords[forger])))
            sessions[-1].declare_queryable(key, answer(b"forged"))
        sessions.append(zenoh.open(router.client_config(sender, pki.passwords[sender])))
        time.sleep(1.0)  # declarations reach the router
        replies = list(sessions[-1].get(key, payload=b'{"action": "open"}', timeout=3.0))
        return sorted(r.ok.payload.to_bytes() for r in replies if r.ok is not None)
    finally:
        for s in sessions:
            s.close()


@pytest.mark.parametrize("user", ["sofia", "detector", "calibrator"])
def test_only_controllers_command_the_gripper(secure_router: SecureRouter, pki: Pki, user: str) -> None:
    assert _gripper_replies(secure_router, pki, user) == [], f"{user} commanded the gripper"


@pytest.mark.parametrize("user", ["arm", "operator"])
def test_controllers_command_the_gripper(secure_router: SecureRouter, pki: Pki, user: str) -> None:
    assert _gripper_replies(secure_router, pki, user) == [b"ok"]


def test_nobody_answers_for_the_gripper(secure_router: SecureRouter, pki: Pki) -> None:
    assert _gripper_replies(secure_router, pki, "arm", forger="sofia") == [b"ok"]
