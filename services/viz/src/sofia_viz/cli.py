"""``sofia viz serve``: the live view for Foxglove (open ws://127.0.0.1:8765 in Foxglove)."""

from __future__ import annotations

import argparse
from pathlib import Path

from sofia_runtime.output import add_command, add_group, emit
from sofia_runtime.zenoh_config import ZenohOptions, add_zenoh_args
from sofia_schemas import Board
from sofia_schemas.board import BOARD_HELP
from sofia_schemas.frames import CAMERA_FRAME
from sofia_schemas.keys import add_robot_arg, default_robot

LAYOUT = Path(__file__).with_name("data") / "layout.json"


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    s = add_group(sub, "viz", "live view in Foxglove (WebSocket server)")
    serve = add_command(s, "serve", _serve, "serve SofIA's bus to Foxglove over WebSocket")
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
    add_command(s, "layout", _layout, "print the path of the saved Foxglove layout", "the path, one object")


def _layout(args: argparse.Namespace) -> int:
    emit(args, {"layout": LAYOUT}, str(LAYOUT))
    return 0


def _serve(args: argparse.Namespace) -> int:
    from .service import ServiceConfig, main

    board = Board.load(args.board)
    config = ServiceConfig(robot=args.robot or default_robot(), zenoh=ZenohOptions.from_args(args), board=board,
                           host=args.host, port=args.port, camera_frame=args.camera_frame)  # fmt: skip
    return main(config)
