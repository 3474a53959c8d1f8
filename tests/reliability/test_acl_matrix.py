"""Deny by default: the shipped secure router (docker/zenoh/router-secure.json5, mTLS, user and
password, access control) against every identity x every key x {exact, ``*``, a prefix wildcard
``$*``, ``**``} x {put, declare subscriber, get, declare queryable}, with real sessions through a
real router and a throwaway CA. Allowed: exactly the rights of :data:`sofia_runtime.acl.RIGHTS`
on exact keys; every wildcard request is denied. The shipped file is also checked to be the
rendering of that table."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator

import pytest
import zenoh
from sofia_runtime.acl import RIGHTS, access_control

from .conftest import REPO, Pki, SecureRouter

ROBOT = "tacl"
KEYS = sorted({k for rights in RIGHTS.values() for keys in rights.values() for k in keys})
GLOBAL = (f"sofia/{ROBOT}/**", "sofia/**", f"sofia/{ROBOT}/**/result", f"sofia/{ROBOT}/*/status")


def variants(key: str) -> dict[str, str]:
    parent, _, last = f"sofia/{ROBOT}/{key}".rpartition("/")
    return {"exact": f"{parent}/{last}", "star": f"{parent}/*", "prefix": f"{parent}/{last[:2]}$*"}


EXPRS = sorted({e for k in KEYS for e in variants(k).values()} | set(GLOBAL))
EXACT = {variants(k)["exact"]: k for k in KEYS}


def allowed(user: str, right: str, expr: str) -> bool:
    return expr in EXACT and EXACT[expr] in RIGHTS[user].get(right, ())


def anyone(right: str, key: str, other_than: str) -> bool:
    """Whether another identity than ``other_than`` has ``right`` on ``key`` (a session's own
    declarations are served inside it, without the router: only pairs of identities are probed)."""
    return any(key in rights.get(right, ()) for user, rights in RIGHTS.items() if user != other_than)


def _set(value: object) -> object:
    """``value`` without the members Zenoh fills with null."""
    if isinstance(value, dict):
        return {k: _set(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_set(v) for v in value]
    return value


def test_shipped_router_config_is_the_table() -> None:
    conf = zenoh.Config.from_file(str(REPO / "docker/zenoh/router-secure.json5"))
    assert _set(json.loads(conf.get_json("access_control"))) == access_control()


@pytest.fixture(scope="module")
def sessions(secure_router: SecureRouter, pki: Pki) -> Iterator[dict[str, zenoh.Session]]:
    opened = {u: zenoh.open(secure_router.client_config(u, pki.passwords[u])) for u in RIGHTS}
    yield opened
    for s in opened.values():
        s.close()


class Probe:
    """Every session declares a subscriber and a queryable on ``exprs``; :meth:`traffic` puts and
    gets every expression from every session. What crossed the router between two identities is
    kept: ``received`` (subscriber, its expr, publisher, its expr) and ``answered`` (querier, its
    expr, answerer, its expr). A session's own declarations are served inside it, and a sample or
    query it was sent reaches all of its matching declarations: only pairs of identities count."""

    def __init__(self, sessions: dict[str, zenoh.Session], exprs: list[str]) -> None:
        self.lock = threading.Lock()
        self.received: set[tuple[str, str, str, str]] = set()
        self.answered: set[tuple[str, str, str, str]] = set()
        self.declared = []
        for user, s in sessions.items():
            for expr in exprs:
                self.declared.append(s.declare_subscriber(expr, self._on_sample(user, expr)))
                self.declared.append(s.declare_queryable(expr, self._on_query(user, expr)))

    def _on_sample(self, user: str, expr: str):  # type: ignore[no-untyped-def]
        def cb(sample: zenoh.Sample) -> None:
            sender = json.loads(sample.payload.to_bytes())
            if sender["user"] != user:
                with self.lock:
                    self.received.add((user, expr, sender["user"], sender["expr"]))

        return cb

    def _on_query(self, user: str, expr: str):  # type: ignore[no-untyped-def]
        def cb(query: zenoh.Query) -> None:
            query.reply(str(query.key_expr), json.dumps({"user": user, "expr": expr}))

        return cb

    def _on_reply(self, user: str, expr: str):  # type: ignore[no-untyped-def]
        def cb(reply: zenoh.Reply) -> None:
            if reply.ok is not None:
                answerer = json.loads(reply.ok.payload.to_bytes())
                if answerer["user"] != user:
                    with self.lock:
                        self.answered.add((user, expr, answerer["user"], answerer["expr"]))

        return cb

    def traffic(self, sessions: dict[str, zenoh.Session], exprs: list[str]) -> None:
        time.sleep(2.0)  # the declarations reach the router and come back to the clients
        for _ in range(3):
            for user, s in sessions.items():
                for expr in exprs:
                    payload = json.dumps({"user": user, "expr": expr})
                    s.put(expr, payload)
                    s.get(expr, handler=self._on_reply(user, expr), timeout=2.0,
                          consolidation=zenoh.ConsolidationMode.NONE)  # fmt: skip
            time.sleep(0.7)
        time.sleep(2.0)

    def close(self) -> None:
        for d in self.declared:
            d.undeclare()


def test_every_identity_key_wildcard_and_operation(sessions: dict[str, zenoh.Session]) -> None:
    """Requests are honoured exactly as the table says: a put or get with a wildcard reaches no one,
    an exact one only within the rights; a subscriber or queryable (exact or wildcard) is only ever
    served the keys of its identity's rights, and an exact one is served them."""
    probe = Probe(sessions, EXPRS)
    probe.traffic(sessions, EXPRS)
    probe.close()
    wrong = []
    for user in RIGHTS:
        for expr in EXPRS:
            key = EXACT.get(expr, "")
            got_keys = {EXACT.get(r[3], r[3]) for r in probe.received if r[:2] == (user, expr)}
            asked_keys = {EXACT.get(a[1], a[1]) for a in probe.answered if a[2:] == (user, expr)}
            answer_keys = {EXACT.get(a[1], a[1]) for a in probe.answered if a[:2] == (user, expr)}
            checks = {
                "put": (any(r[2:] == (user, expr) for r in probe.received),
                        allowed(user, "pub", expr) and anyone("sub", key, user)),
                "get": (bool(answer_keys), allowed(user, "query", expr) and anyone("answer", key, user)),
            }  # fmt: skip
            if expr in EXACT:
                checks["subscribe"] = (
                    bool(got_keys),
                    allowed(user, "sub", expr) and anyone("pub", key, user),
                )
                checks["queryable"] = (
                    bool(asked_keys),
                    allowed(user, "answer", expr) and anyone("query", key, user),
                )
            wrong += [f"{user} {op} {expr}: {'allowed' if got else 'denied'}, expected "
                      f"{'allowed' if want else 'denied'}" for op, (got, want) in checks.items() if got != want]  # fmt: skip
            wrong += [
                f"{user} subscribed {expr} received {k}" for k in got_keys - set(RIGHTS[user].get("sub", ()))
            ]
            wrong += [
                f"{user} queryable {expr} asked for {k}"
                for k in asked_keys - set(RIGHTS[user].get("answer", ()))
            ]
    n = len(RIGHTS) * len(EXPRS) * 4
    print(f"{n} probes ({len(RIGHTS)} identities x {len(EXPRS)} key expressions x 4 operations), "
          f"{len(probe.received)} deliveries, {len(probe.answered)} replies; {len(wrong)} wrong")  # fmt: skip
    assert not wrong, "\n".join(wrong[:40])


def test_wildcard_declarations_are_served_nothing(secure_router: SecureRouter, pki: Pki,
                                                  sessions: dict[str, zenoh.Session]) -> None:  # fmt: skip
    """A second session per identity with only wildcard subscribers and queryables, while every
    identity puts and gets every exact key: nothing reaches them."""
    wildcards = [e for e in EXPRS if e not in EXACT]
    probers = {u: zenoh.open(secure_router.client_config(u, pki.passwords[u])) for u in RIGHTS}
    try:
        probe = Probe(probers, wildcards)
        probe.traffic(sessions, sorted(EXACT))
        probe.close()
    finally:
        for s in probers.values():
            s.close()
    leaks = [r for r in probe.received if r[1] in wildcards] + [
        a for a in probe.answered if a[3] in wildcards
    ]
    print(f"{len(RIGHTS) * len(wildcards) * 2} wildcard declarations, {len(leaks)} served")
    assert not leaks, leaks[:20]
