"""``sofia camera ...``: the camera service, the connected cameras, recording, the simulation's truth."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sofia_runtime.output import add_command, add_group, emit, fields_text
from sofia_runtime.zenoh_config import ZenohOptions, add_zenoh_args
from sofia_schemas.keys import add_robot_arg, default_robot

from .errors import CameraError

MODES = ("640x480", "848x480", "1280x720")


def _add_sim_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("simulation (--sim)")
    # fmt: off
    g.add_argument("--sim-scene", choices=("calibration", "board", "eye-to-hand", "ball"),
                   default="calibration", help="the blob sheet for calibration, the board with objects, eye-to-hand: "
                   "the camera on a fixed mount and a ball on the flange, or ball: a ball on the table at "
                   "--sim-target's x y, radius --sim-ball's R (default calibration)")
    g.add_argument("--sim-T-base-cam", metavar="'x y z qx qy qz qw'|FILE", dest="sim_T_base_cam",
                   help="eye-to-hand scene: the fixed camera's colour optical frame in the base frame (as "
                   "--sim-T-flange-cam; default: 0.75 m in front of the robot, looking back at the workspace)")
    g.add_argument("--sim-ball", nargs=4, type=float, metavar=("X", "Y", "Z", "R"),
                   help="eye-to-hand scene: the ball's centre in the flange frame and its radius, metres "
                   "(default 0 0 0.1 0.025); ball scene: its radius R")
    g.add_argument("--sim-T-flange-cam", metavar="'x y z qx qy qz qw'|FILE", dest="sim_T_flange_cam",
                   help="true flange -> colour optical frame (metres, quaternion x y z w) or a YAML/JSON "
                   "file with matrix or translation + quaternion_xyzw (default: the synthetic data's)")
    g.add_argument("--sim-target", nargs=3, type=float, metavar=("X", "Y", "Z"),
                   help="calibration scene: blob centre in the base frame, metres (default 0.45 0.25 -0.0495); "
                   "ball scene: the ball's x y (resting on the table unless z is higher)")
    g.add_argument("--sim-blob-radius", type=float, default=0.015, metavar="M", help="blob radius (default 0.015)")
    g.add_argument("--sim-seed", type=int, default=0, help="board scene and noise seed (default 0)")
    g.add_argument("--sim-kind", choices=("one", "two", "nonred", "empty", "sort"), default="one",
                   help="board scene: objects on the board (default one, on a red field; sort: a yellow, a green, "
                   "a blue and a purple object on the first two rows)")
    g.add_argument("--sim-board", type=Path, metavar="FILE", help="board YAML/JSON (default: the package's)")
    g.add_argument("--sim-world", type=Path, metavar="FILE",
                   help="board and eye-to-hand scenes: the world file shared with the arm and the gripper emulator, written "
                        "here when missing (default: $SOFIA_SIM_WORLD); objects are rendered where it says")
    g.add_argument("--sim-noise", choices=("d435", "stereo", "none"), default="d435",
                   help="d435: depth noise, dropouts, edge removal; stereo: the active-stereo model (right-imager "
                   "shadows, flying pixels, disparity steps; slower); none: exact geometry (default d435)")
    # fmt: on


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    cs = add_group(sub, "camera", "RealSense D435: service, list, record, simulation")

    s = add_command(cs, "serve", _serve, "publish the camera's organized clouds and camera info")
    s.add_argument("--serial", help="camera serial number (default: the first connected)")
    # fmt: off
    s.add_argument("--width", type=int, default=640, help="frame width, pixels: 640, 848 or 1280 (default 640)")
    s.add_argument("--height", type=int, default=480, help="frame height, pixels: 480 or 720 (default 480)")
    s.add_argument("--fps", type=int, default=30, help="frame rate, Hz: 6, 15 or 30 (default 30)")
    s.add_argument("--preset", help="visual preset: default, high_accuracy, high_density, medium_density, hand")
    s.add_argument("--filters", default="none", help="comma-separated librealsense filters: "
                   "decimation,spatial,temporal,hole_filling (default none)")
    s.add_argument("--align", choices=("registration", "librealsense"), default="registration",
                   help="how depth is put on the colour grid: the service's own registration (default) or rs.align")
    s.add_argument("--max-skew-ms", type=float, help="colour-depth offset still called one instant "
                   "(default: half a frame)")
    s.add_argument("--drop-unsynced", action="store_true",
                   help="do not publish clouds whose colour is of another instant (default: publish, flagged)")
    s.add_argument("--depth-correction", choices=("auto", "off"), default="auto",
                   help="apply the calibration result's depth correction (auto) or never (off)")
    add_robot_arg(s)
    s.add_argument("--sim", action="store_true", help="frames from the simulated D435 at the live flange pose")
    # fmt: on
    _add_sim_args(s)
    add_zenoh_args(s)

    add_command(cs, "list", _list, "connected cameras: name, serial, firmware, USB type",
                "one object per camera and line")  # fmt: skip
    r = add_command(cs, "record", _record,
                    "record camera clouds, camera info and flange poses from the bus to MCAP", "the file and the message counts, one object")  # fmt: skip
    r.add_argument("out", type=Path, metavar="OUT.mcap", help="MCAP file to write")
    r.add_argument("--seconds", type=float, required=True, help="how long to record, seconds (required)")
    add_robot_arg(r)
    add_zenoh_args(r)
    t = add_command(
        cs, "sim-truth", _truth, "print the ground truth of a simulated scene", "the truth, one object"
    )
    _add_sim_args(t)


def sim_options(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from sofia_schemas.sim_world import world_path

    from .sim_fixed import DEFAULT_BALL_FLANGE, DEFAULT_BALL_RADIUS, DEFAULT_T_BASE_CAM
    from .sim_scene import DEFAULT_TARGET, SimOptions, parse_T_flange_cam

    ball = (*DEFAULT_BALL_FLANGE, DEFAULT_BALL_RADIUS) if args.sim_ball is None else args.sim_ball
    return SimOptions(
        scene=args.sim_scene, T_flange_cam=parse_T_flange_cam(args.sim_T_flange_cam),
        T_base_cam=parse_T_flange_cam(args.sim_T_base_cam, "--sim-T-base-cam", DEFAULT_T_BASE_CAM),
        ball_flange=tuple(ball[:3]), ball_radius=ball[3],
        target_base=tuple(args.sim_target) if args.sim_target else DEFAULT_TARGET,
        blob_radius=args.sim_blob_radius, seed=args.sim_seed, kind=args.sim_kind, board_file=args.sim_board,
        noise=args.sim_noise != "none",
        stereo=args.sim_noise == "stereo", world_file=args.sim_world or world_path(),
    )  # fmt: skip


def _serve(args: argparse.Namespace) -> int:
    from .intrinsics import d435_spec
    from .processing import parse_filters
    from .service import ServiceConfig, main

    try:
        d435_spec(args.width, args.height, args.fps)
        conf = ServiceConfig(
            robot=args.robot or default_robot(), zenoh=ZenohOptions.from_args(args), width=args.width,
            height=args.height, fps=args.fps, serial=args.serial, preset=args.preset,
            filters=parse_filters(args.filters), max_skew_ms=args.max_skew_ms, drop_unsynced=args.drop_unsynced,
            depth_correction=args.depth_correction == "auto", sim=sim_options(args) if args.sim else None,
            align=args.align,
        )  # fmt: skip
    except CameraError as e:
        print(f"sofia camera serve: {e}", file=sys.stderr)
        return 2
    return main(conf)


def _list(args: argparse.Namespace) -> int:
    from .device import list_devices

    cameras = list_devices()
    if args.json:
        for cam in cameras:
            emit(args, cam, "")
        return 0 if cameras else 1
    if not cameras:
        print("no RealSense camera connected (check the USB 3 cable, `lsusb | grep 8086`, the udev rules)")
        return 1
    print(f"{'name':34} {'serial':14} {'firmware':14} usb")
    for cam in cameras:
        print(f"{cam.get('name', '?'):34} {cam.get('serial', '?'):14} {cam.get('firmware', '?'):14} "
              f"{cam.get('usb_type', '?')}")  # fmt: skip
    return 0


def _record(args: argparse.Namespace) -> int:
    from .record import record

    counts = record(args.out, args.seconds, args.robot or default_robot(), ZenohOptions.from_args(args))
    text = f"{args.out}: " + ", ".join(f"{n} {what}" for what, n in counts.items())
    emit(args, {"file": args.out, "counts": counts}, text)
    return 0 if counts.get("clouds") else 1


def _truth(args: argparse.Namespace) -> int:
    from .sim_scene import SimWorld

    try:
        world = SimWorld(sim_options(args))
    except CameraError as e:
        print(f"sofia camera sim-truth: {e}", file=sys.stderr)
        return 2
    truth = world.truth()
    emit(args, truth, lambda: fields_text(truth))
    return 0
