"""Bus tools for people: ``sofia echo``, ``sofia query``, ``sofia health`` and ``sofia router``."""

from __future__ import annotations

import argparse
import json
import logging
import re
import sys
import threading
from pathlib import Path

import zenoh
from sofia_schemas.keys import Keys, add_robot_arg, default_robot
from sofia_schemas.messages import ServiceStatus

from .client import QueryError, ask, is_timeout
from .client import query as query_replies
from .decode import describe
from .output import add_command, emit
from .service import StopFlag
from .zenoh_config import ZenohOptions, add_zenoh_args, resolve, zenoh_config

log = logging.getLogger("sofia.bus")
EXIT_DEGRADED = 3  # `sofia health`: the service answers but says it is degraded


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = add_command(sub, "echo", echo, "print what arrives on a key expression",
                    "one object per message and line", description="Print what arrives on a key expression: "
                    "JSON pretty-printed, point clouds summarised. Exit 1 when --count messages did not arrive "
                    "before --timeout.")  # fmt: skip
    p.add_argument("key", help="key expression, e.g. 'sofia/panda/detector/detections' or 'sofia/**'")
    p.add_argument("--count", type=int, default=0, metavar="N",
                   help="stop after N messages (default 0: until Ctrl-C)")  # fmt: skip
    p.add_argument("--timeout", type=float, default=0.0, metavar="S",
                   help="stop after S seconds (default 0: no limit)")  # fmt: skip
    add_zenoh_args(p)

    p = add_command(sub, "query", query, "send a query and print the replies", "one object per reply and line",
                    description="Send a query and print every reply. Exit 1 on an error reply or no reply, "
                    "2 when the --payload file is missing.")  # fmt: skip
    p.add_argument("key", help="e.g. sofia/panda/detector/detect")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--payload", type=Path, metavar="FILE", help="file whose bytes are the query payload, "
                   "e.g. a cloud from `sofia replay export` (default: no payload)")  # fmt: skip
    g.add_argument("--data", help="the query payload as a string, e.g. JSON (default: no payload)")
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="seconds to wait for replies (default 10)")  # fmt: skip
    add_zenoh_args(p)

    p = add_command(sub, "health", health, "exit 0 when SERVICE answers its status and is healthy",
                    "the service's status, one object", description="Ask SERVICE for its status. Exit 0 when "
                    "it is ok, 3 when it is degraded (0 with --degraded-ok), 1 when it is in error or does not "
                    "answer.")  # fmt: skip
    p.add_argument("service", help="detector, calibrator, gripper, replay")
    p.add_argument("--degraded-ok", action="store_true",
                   help="exit 0 on degraded too (e.g. a detector before its first calibration)")  # fmt: skip
    add_robot_arg(p)
    p.add_argument("--timeout", type=float, default=5.0, metavar="S",
                   help="seconds to wait for the status (default 5)")  # fmt: skip
    add_zenoh_args(p)

    p = add_command(sub, "router", router, "run a Zenoh router (what `sofia up` starts)",
                    description="A Zenoh router on its own, until Ctrl-C; --listen sets where it listens.")  # fmt: skip
    add_zenoh_args(p)
    for action in p._actions:  # a router is always in router mode: the option is not offered
        if action.dest == "zenoh_mode":
            action.help = argparse.SUPPRESS


def _print(key: str, payload: bytes, encoding: str, as_json: bool) -> None:
    desc = describe(payload, encoding)
    if as_json:
        print(json.dumps({"key": key, "encoding": encoding, **desc}), flush=True)
    else:
        print(f"── {key}  [{encoding or 'no encoding'}]", flush=True)
        print(json.dumps(desc.get("json", desc), indent=2), flush=True)


def echo(args: argparse.Namespace) -> int:
    stop, count, lock = StopFlag(), 0, threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        nonlocal count
        with lock:  # samples keep arriving until the session closes: print no more than --count
            if args.count and count >= args.count:
                return
            _print(str(sample.key_expr), sample.payload.to_bytes(), str(sample.encoding), args.json)
            count += 1
            if args.count and count >= args.count:
                stop.set()

    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        session.declare_subscriber(args.key, on_sample)
        log.info("listening on %s", args.key)
        stop.wait(args.timeout or None)
    if args.count and count < args.count:
        print(f"sofia echo: {count} of {args.count} messages on {args.key} within {args.timeout:g} s",
              file=sys.stderr)  # fmt: skip
        return 1
    return 0


def query(args: argparse.Namespace) -> int:
    if args.payload is not None and not args.payload.is_file():
        print(f"sofia query: error: --payload file {str(args.payload)!r} does not exist "
              "(`sofia replay export FILE.mcap --out cloud.cdr` writes one)", file=sys.stderr)  # fmt: skip
        return 2
    payload = args.payload.read_bytes() if args.payload else (args.data.encode() if args.data else None)
    n_ok = n_err = 0
    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        for reply in query_replies(session, args.key, payload, args.timeout):
            if reply.ok is not None:
                n_ok += 1
                s = reply.ok
                _print(str(s.key_expr), s.payload.to_bytes(), str(s.encoding), args.json)
            elif (err := reply.err) is not None:
                if is_timeout(err):  # Zenoh's own "Timeout": no queryable answered in time
                    continue
                n_err += 1
                desc = describe(err.payload.to_bytes(), str(err.encoding))
                error = {"key": args.key, "error": desc.get("json", desc)}
                emit(args, error, f"── error reply from {args.key}\n{json.dumps(error['error'], indent=2)}")
    if n_ok == 0 and n_err == 0:
        print(f"sofia query: no reply from {args.key} within {args.timeout} s", file=sys.stderr)
        return 1
    return 1 if n_err else 0


def health(args: argparse.Namespace) -> int:
    key = Keys(args.robot or default_robot()).status(args.service)
    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        try:
            status = ask(session, key, ServiceStatus, timeout=args.timeout)
        except (QueryError, ValueError) as e:  # no or an error reply; an unreadable status
            if args.json:
                emit(args, {"service": args.service, "state": "unreachable", "detail": str(e)}, "")
            else:
                print(f"{args.service}: {e}", file=sys.stderr)
            return 1
    emit(args, status, f"{args.service}: {status.state} {status.detail}".rstrip())
    if status.state == "ok" or (status.state == "degraded" and args.degraded_ok):
        return 0
    return EXIT_DEGRADED if status.state == "degraded" else 1


def router(args: argparse.Namespace) -> int:
    options = ZenohOptions.from_args(args)
    if options.mode not in (None, "router"):
        print(f"sofia router: error: a router runs in router mode, not {options.mode!r}", file=sys.stderr)
        return 2
    options.mode = "router"
    stop = StopFlag()
    try:
        session = zenoh.open(zenoh_config(options))
    except zenoh.ZError as e:  # e.g. the port is taken by another router
        print(f"sofia router: error: {_listen_error(e, options)}", file=sys.stderr)
        return 2
    with session:
        log.info("router ready: zid %s", session.zid())
        stop.wait()
    log.info("router stopped")
    return 0


def _listen_error(error: BaseException, options: ZenohOptions) -> str:
    """Zenoh's listener error in one line: the endpoint and the OS's reason, without its source
    locations (``... bound to tcp/127.0.0.1:7447: [...: Address already in use (os error 98) at ...``)."""
    text = str(error)
    where = re.search(r"bound to (\S+?):? \[", text)
    reason = re.search(r"([A-Z][^:\[\]]*\(os error \d+\))", text)
    if where is None:
        endpoints = resolve(options).get("listen") or []
        where_text = ", ".join(map(str, endpoints)) or "its endpoints"  # type: ignore[call-overload]
    else:
        where_text = where.group(1)
    why = reason.group(1) if reason else text.split(" at /", 1)[0]
    return f"cannot listen on {where_text}: {why[0].lower()}{why[1:]}"
