"""``sofia ros2 serve`` and ``sofia ros2 types`` (the shipped ROS 2 types and their RIHS01 hashes)."""

from __future__ import annotations

import argparse
import os

from sofia_schemas.frames import BASE_FRAME, CAMERA_FRAME, FLANGE_FRAME
from sofia_schemas.keys import add_robot_arg, default_robot

from ..output import add_json_option, emit
from ..zenoh_config import ZenohOptions, add_zenoh_args


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("ros2", help="SofIA on the ROS 2 graph (rmw_zenoh): topics, services, tf")
    s = p.add_subparsers(dest="ros2_cmd", required=True)
    serve = s.add_parser("serve", help="offer SofIA's topics and services to ROS 2 nodes using rmw_zenoh")
    add_robot_arg(serve)
    serve.add_argument("--domain", type=int, default=None, help="ROS domain id (default $ROS_DOMAIN_ID or 0)")
    serve.add_argument(
        "--camera-frame",
        default=CAMERA_FRAME,
        help="child frame of the calibration on /tf_static (the clouds' frame_id)",
    )
    serve.add_argument(
        "--camera-topic",
        default="/camera/camera/depth/color/points",
        help="ROS 2 PointCloud2 topic taken in as camera-frame clouds ('' for none)",
    )
    serve.add_argument("--no-tf-input", action="store_true", help="do not take the flange pose from /tf")
    serve.add_argument(
        "--base-frame", default=BASE_FRAME, help="robot base frame on /tf (default %(default)s)"
    )
    serve.add_argument(
        "--flange-frame", default=FLANGE_FRAME, help="flange frame on /tf (default %(default)s)"
    )
    add_zenoh_args(serve)
    serve.set_defaults(func=_serve)
    types = s.add_parser("types", help="print the shipped ROS 2 types with their RIHS01 type hashes")
    add_json_option(types, "one object per type and line")
    types.set_defaults(func=_types)


def _serve(args: argparse.Namespace) -> int:
    from .bridge import BridgeConfig
    from .service import ServiceConfig, main

    bridge = BridgeConfig(
        robot=args.robot or default_robot(), domain=args.domain, camera_frame=args.camera_frame,
        camera_topic=args.camera_topic, tf_input=not args.no_tf_input, base_frame=args.base_frame,
        flange_frame=args.flange_frame,
    )  # fmt: skip
    return main(ServiceConfig(bridge, ZenohOptions.from_args(args)))


def _types(args: argparse.Namespace) -> int:
    from sofia_schemas.ros2.typesupport import dds_type_name, shipped_types, type_hash

    for name in shipped_types():
        dds, rihs = dds_type_name(name), type_hash(name)
        emit(args, {"type": name, "dds_type": dds, "type_hash": rihs}, f"{name:40s} {dds:50s} {rihs}")
    return 0


def enabled(env: dict[str, str] | None = None) -> bool:
    """``$SOFIA_ROS2`` is set to 1/true/yes/on."""
    value = (env if env is not None else os.environ).get("SOFIA_ROS2", "")
    return value.strip().lower() in ("1", "true", "yes", "on")
