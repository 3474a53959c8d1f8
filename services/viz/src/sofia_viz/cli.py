"""``sofia viz serve``: the live view for Foxglove (open ws://127.0.0.1:8765 in Foxglove)."""

from __future__ import annotations

import argparse
from pathlib import Path

from sofia_runtime.output import add_json_option, emit
from sofia_runtime.zenoh_config import ZenohOptions, add_zenoh_args
from sofia_schemas import Board
from sofia_schemas.board import BOARD_HELP
from sofia_schemas.frames import CAMERA_FRAME
from sofia_schemas.keys import add_robot_arg, default_robot

LAYOUT = Path(__file__).with_name("data") / "layout.json"


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("viz", help="live view in Foxglove (WebSocket server)")
    s = p.add_subparsers(dest="viz_cmd", required=True)
    serve = s.add_parser("serve", help="serve SofIA's bus to Foxglove over WebSocket")
    serve.add_argument(
        "--host", default="127.0.0.1", help="address to listen on (0.0.0.0 for other machines)"
    )
    serve.add_argument(
        "--port", type=int, default=8765, help="WebSocket TCP port number (0: any free port; default 8765)"
    )
    serve.add_argument("--board", type=Path, default=None, help=BOARD_HELP)
    serve.add_argument("--camera-frame", default=CAMERA_FRAME,
                       help="frame_id of the camera clouds (default %(default)s)")  # fmt: skip
    add_robot_arg(serve)
    add_zenoh_args(serve)
    serve.set_defaults(func=_serve)
    layout = s.add_parser("layout", help="print the path of the saved Foxglove layout")
    add_json_option(layout, "the path, one object")
    layout.set_defaults(func=_layout)


def _layout(args: argparse.Namespace) -> int:
    emit(args, {"layout": LAYOUT}, str(LAYOUT))
    return 0


def _serve(args: argparse.Namespace) -> int:
    from .service import ServiceConfig, main

    board = Board.load(args.board)
    config = ServiceConfig(robot=args.robot or default_robot(), zenoh=ZenohOptions.from_args(args), board=board,
                           host=args.host, port=args.port, camera_frame=args.camera_frame)  # fmt: skip
    return main(config)
