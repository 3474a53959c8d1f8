"""``sofia calibrate`` (for people: files in, calibration out) and ``sofia calibrator`` (the service)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from importlib.metadata import entry_points
from typing import Any

import numpy as np
from sofia_runtime.output import add_json_option
from sofia_runtime.zenoh_config import add_zenoh_args
from sofia_schemas.keys import add_robot_arg
from sofia_schemas.transforms import make_transform

from .errors import InputMismatch
from .fitting.calibrate import CHILD_FRAME, PARENT_FRAME
from .inbox import QUERY_DEADLINE_S
from .samples.store import MAX_SAMPLES

log = logging.getLogger(__name__)

# modes under `sofia calibrate` that other packages add (the arm's `auto`): each entry point is a
# function called with the `calibrate` parser
CALIBRATE_MODES = "sofia.calibrate_modes"
GUESS_QUAT_TOL = 0.01  # a typed guess quaternion within 1 % of unit norm is normalised


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "calibrate", help="hand-eye calibration T_flange_cam from blob samples",
        description="Calibrate the flange-mounted camera (T_flange_cam: camera points into the flange "
        "frame, metres) from a blob seen from several flange poses. No initial guess is needed.",
    )  # fmt: skip
    src = p.add_argument_group("samples (one of)")
    src.add_argument("--poses", help="lab poses.txt: blob x,y,z per line, camera frame, metres")
    src.add_argument("--tfs", help="lab tfs.txt: flange poses (translation + rotation x y z w blocks)")
    src.add_argument("--joints", help="Panda joint positions, 7 per line (radians), paired with --poses")
    src.add_argument("--samples", help="CSV or JSON sample file")
    src.add_argument("--mcap", help="MCAP recording with blob observations and flange poses")
    src.add_argument(
        "--from-clouds", action="store_true", help="with --mcap: extract the blob from the clouds"
    )
    add_target_args(p)
    p.add_argument("--guess", nargs=7, type=float, metavar=("X", "Y", "Z", "QX", "QY", "QZ", "QW"),
                   help="optional initial T_flange_cam (never required); quaternion x y z w")  # fmt: skip
    p.add_argument("--loss", default="linear", choices=("linear", "huber", "cauchy"),
                   help="robust loss of the fit: linear = least squares (default linear)")  # fmt: skip
    p.add_argument(
        "--noise", default="auto", choices=("auto", "depth", "uniform"),
        help="noise model, its level estimated from the data: auto = isotropic + the D435's (default)",
    )  # fmt: skip
    p.add_argument(
        "--correction", default="auto", choices=("auto", "rigid", "depth_scale", "ray_scale"),
        help="camera correction fitted with the transform: auto = chosen by an F-test (default)",
    )  # fmt: skip
    add_frame_args(p)
    p.add_argument("--keep-outliers", action="store_true", help="report the fit with every sample")
    add_json_option(p, "the CalibrationResult, one object", text="YAML")
    p.add_argument("--yaml", metavar="OUT", help="also write the result as YAML")
    p.add_argument("--plot", metavar="OUT.png", help="write the dissipation plot")
    p.set_defaults(func=run_calibrate)
    for ep in sorted(entry_points(group=CALIBRATE_MODES), key=lambda e: e.name):
        try:
            ep.load()(p)
        except ImportError as e:  # a package whose optional dependencies are missing
            log.debug("calibrate mode %s unavailable: %s", ep.name, e)

    c = sub.add_parser("calibrator", help="the calibrator service")
    cs = c.add_subparsers(dest="calibrator_cmd", required=True, metavar="ACTION")
    s = cs.add_parser("serve", help="run the online calibrator service on Zenoh")
    s.add_argument("--state-dir", default="./var/calibrator", help="sample database and saved results")
    s.add_argument("--from-clouds", action="store_true", help="also extract the blob from camera clouds")
    s.add_argument("--cloud-target", choices=("blob", "ball"), default="blob",
                   help="with --from-clouds: the blob on the sheet, or a coloured ball (default blob)")  # fmt: skip
    s.add_argument(
        "--ball-radius", type=float, metavar="M", help="the ball's radius, metres (default: fitted)"
    )
    s.add_argument("--setup", choices=("eye-in-hand", "eye-to-hand"), default="eye-in-hand",
                   help="solve T_flange_cam (eye-in-hand) or T_base_cam (eye-to-hand: the target on the "
                   "flange); a solve query's options may change it (default eye-in-hand)")  # fmt: skip
    s.add_argument("--tolerance-ms", type=float, default=50.0, help="pose/blob stamp gap, ms")
    s.add_argument("--min-samples", type=int, default=3, help="samples before the first solve")
    s.add_argument("--max-samples", type=int, default=MAX_SAMPLES,
                   help=f"samples kept at most; more are refused (default {MAX_SAMPLES})")  # fmt: skip
    s.add_argument("--query-deadline", type=_seconds, default=QUERY_DEADLINE_S, metavar="S",
                   help="a query the worker reaches more than S seconds after it arrived is answered "
                   f"'busy, retry' (default {QUERY_DEADLINE_S:g}; clients wait 10 s)")  # fmt: skip
    add_robot_arg(s)
    add_frame_args(s)
    add_zenoh_args(s)
    s.set_defaults(func=run_service)


def _seconds(text: str) -> float:
    """A duration from the command line: a positive, finite number of seconds."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"{text} is not a positive number of seconds")
    return value


def add_target_args(p: argparse.ArgumentParser) -> None:
    """--target / --setup and the inputs of the sphere and pose targets."""
    g = p.add_argument_group("target and set-up")
    g.add_argument("--target", default="blob", choices=("blob", "sphere", "poses", "charuco", "apriltag"),
                   help="what the camera sees: blob (default), sphere (--clouds), poses (--pose-pairs), "
                   "charuco (--images, --camera-matrix, --board), apriltag (--images, --camera-matrix, --tag-size)")  # fmt: skip
    g.add_argument("--setup", default="eye-in-hand", choices=("eye-in-hand", "eye-to-hand"),
                   help="eye-in-hand: camera on the flange (T_flange_cam, default); eye-to-hand: camera "
                   "fixed, target on the flange (T_base_cam)")  # fmt: skip
    g.add_argument("--clouds", nargs="+", metavar="CLOUD", help="sphere: one PCD/PLY cloud per flange pose")
    g.add_argument("--cloud-unit", type=float, default=1.0, help="metres per cloud unit (default 1)")
    g.add_argument("--radius", type=float, help="sphere radius, metres (default: fitted)")
    g.add_argument("--euler-poses", metavar="FILE",
                   help="flange poses as 'a, b, c, x, y, z' lines (radians; see --euler-convention)")  # fmt: skip
    g.add_argument("--euler-convention", default="xyz", help="SciPy Euler sequence (default xyz)")
    g.add_argument(
        "--length-unit", type=float, default=1e-3, help="metres per --euler-poses unit (default mm)"
    )
    g.add_argument("--pose-pairs", metavar="FILE",
                   help="poses: OpenCV YAML of T1_i (flange) / T2_i (target in camera) pairs")  # fmt: skip
    g.add_argument(
        "--images", nargs="+", metavar="IMAGE", help="charuco: one rectified image per flange pose"
    )
    g.add_argument("--camera-matrix", metavar="'fx fy cx cy'|FILE",
                   help="charuco: the images' intrinsics (pixels), or a YAML/JSON file with K or fx fy cx cy")  # fmt: skip
    g.add_argument("--board", nargs=4, type=float, metavar=("COLS", "ROWS", "SQUARE", "MARKER"),
                   help="charuco: squares across and down, square and marker sides in metres (default 7 5 0.04 0.03)")  # fmt: skip
    g.add_argument(
        "--board-dict", default="DICT_5X5_100", help="charuco: the ArUco dictionary (default DICT_5X5_100)"
    )
    g.add_argument(
        "--tag-size",
        type=float,
        default=0.08,
        help="apriltag: the black square's side, metres (default 0.08)",
    )
    g.add_argument(
        "--tag-family",
        default="DICT_APRILTAG_36h11",
        help="apriltag: OpenCV's dictionary (default DICT_APRILTAG_36h11)",
    )
    g.add_argument("--tag-id", type=int, default=0, help="apriltag: the tag's id (default 0)")


def run_target(args: argparse.Namespace) -> object:
    """The calibration of ``--target`` / ``--setup`` (any target but the plain eye-in-hand blob)."""
    from .any_target import PLANNED, calibrate_target, frames

    parent, child = frames(args.setup)
    parent = parent if args.parent_frame == PARENT_FRAME else args.parent_frame
    child = child if args.child_frame == CHILD_FRAME else args.child_frame
    common: dict[str, Any] = {"parent_frame": parent, "child_frame": child}
    if args.target in PLANNED:
        raise InputMismatch(
            f"--target {args.target} is not available yet: give its poses with --target poses"
        )
    if args.target == "poses":
        from .targets.files import read_opencv_pose_pairs

        if not args.pose_pairs:
            raise InputMismatch("--target poses needs --pose-pairs FILE")
        T, T_cam_target = read_opencv_pose_pairs(args.pose_pairs)
        return calibrate_target("poses", args.setup, T_base_flange=T, T_cam_target=T_cam_target, **common)
    if args.target in ("charuco", "apriltag"):
        return calibrate_target(args.target, args.setup, **image_inputs(args), **common)
    if args.euler_poses:
        from .targets.files import read_euler_poses

        T = read_euler_poses(args.euler_poses, args.euler_convention, args.length_unit)
    elif args.target == "sphere" and args.tfs:
        from .inputs.lab import read_tfs

        T = read_tfs(args.tfs)
    else:
        p_cam, T = load_samples(args)
    options: dict[str, Any] = {"sigma": args.noise, "loss": args.loss, "exclude_outliers": not args.keep_outliers,
               "correction": args.correction, **common}  # fmt: skip
    if args.target == "sphere":
        from .targets.files import read_cloud

        if not args.clouds:
            raise InputMismatch("--target sphere needs --clouds, one cloud file per flange pose")
        if len(args.clouds) != len(T):
            raise InputMismatch(f"{len(args.clouds)} clouds but {len(T)} flange poses")
        clouds = [read_cloud(c) * args.cloud_unit for c in args.clouds]
        return calibrate_target("sphere", args.setup, T_base_flange=T, clouds_cam=clouds, radius_m=args.radius,
                                **options)  # fmt: skip
    return calibrate_target(args.target, args.setup, T_base_flange=T, p_cam=p_cam, **options)


def image_inputs(args: argparse.Namespace) -> dict[str, Any]:
    """T_base_flange (--tfs or --euler-poses), the grey images, K and the board or the tag of
    --target charuco or apriltag."""
    from .targets.apriltag import TagSpec
    from .targets.charuco import BoardSpec
    from .targets.files import read_camera_matrix, read_euler_poses, read_grey_images

    if not args.images or not args.camera_matrix:
        raise InputMismatch(
            f"--target {args.target} needs --images (one per flange pose) and --camera-matrix"
        )
    if args.euler_poses:
        T = read_euler_poses(args.euler_poses, args.euler_convention, args.length_unit)
    elif args.tfs:
        from .inputs.lab import read_tfs

        T = read_tfs(args.tfs)
    else:
        raise InputMismatch(
            f"--target {args.target} needs the flange poses: --tfs FILE or --euler-poses FILE"
        )
    if len(args.images) != len(T):
        raise InputMismatch(f"{len(args.images)} images but {len(T)} flange poses")
    inputs = {
        "T_base_flange": T,
        "images": read_grey_images(args.images),
        "K": read_camera_matrix(args.camera_matrix),
    }
    if args.target == "apriltag":
        return {**inputs, "tag": TagSpec(args.tag_family, args.tag_id, args.tag_size)}
    import cv2

    if not args.board_dict.startswith("DICT_") or not hasattr(cv2.aruco, args.board_dict):
        raise InputMismatch(
            f"--board-dict {args.board_dict!r} is not an OpenCV ArUco dictionary (e.g. DICT_5X5_100)"
        )
    board = BoardSpec(dictionary=args.board_dict) if args.board is None else BoardSpec(
        (int(args.board[0]), int(args.board[1])), args.board[2], args.board[3], args.board_dict
    )  # fmt: skip
    return {**inputs, "board": board}


def add_frame_args(p: argparse.ArgumentParser) -> None:
    """--parent-frame / --child-frame, defaulting to the lab's launch file."""
    p.add_argument("--parent-frame", default=PARENT_FRAME, help=f"flange frame (default {PARENT_FRAME})")
    p.add_argument("--child-frame", default=CHILD_FRAME, help=f"camera frame (default {CHILD_FRAME})")


def load_samples(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray]:
    """(p_cam, T_base_flange) from whichever source the arguments name."""
    from .inputs.lab import read_lab, read_poses
    from .inputs.sample_files import read_joints, read_samples

    if args.mcap:
        from .inputs.mcap import read_mcap

        m = read_mcap(args.mcap, from_clouds=args.from_clouds)
        for r in m.rejected:
            print(f"skipped: {r}", file=sys.stderr)
        return m.p_cam, m.T_base_flange
    if args.samples:
        return read_samples(args.samples)
    if args.poses and args.tfs:
        return read_lab(args.poses, args.tfs)
    if args.poses and args.joints:
        p_cam, T = read_poses(args.poses), read_joints(args.joints)
        if len(p_cam) != len(T):
            raise InputMismatch(
                f"{args.poses} has {len(p_cam)} blob positions but {args.joints} has {len(T)} joint rows"
            )
        return p_cam, T
    raise InputMismatch("give --poses with --tfs or --joints, or --samples FILE, or --mcap FILE")


def run_calibrate(args: argparse.Namespace) -> int:
    from .fitting.calibrate import calibrate

    if args.target != "blob" or args.setup != "eye-in-hand":
        return _report(run_target(args), args)
    p_cam, T = load_samples(args)
    guess = None
    if args.guess:
        g = np.array(args.guess)
        norm = float(np.linalg.norm(g[3:]))
        if abs(norm - 1.0) < GUESS_QUAT_TOL:  # hand-typed: normalise small rounding errors
            g[3:] /= norm
        guess = make_transform(g[:3], g[3:])
    cal = calibrate(
        p_cam, T, guess=guess, sigma=args.noise, loss=args.loss, exclude_outliers=not args.keep_outliers,
        correction=args.correction, parent_frame=args.parent_frame, child_frame=args.child_frame,
    )  # fmt: skip
    return _report(cal, args)


def _report(cal: Any, args: argparse.Namespace) -> int:
    """Print and write a calibration's result (YAML or JSON, --yaml, --plot); 0 when it passes."""
    from .formats import to_message, to_yaml

    msg = to_message(cal)
    if args.yaml:
        with open(args.yaml, "w") as f:
            f.write(to_yaml(msg))
    if args.plot:
        from .plot import plot_calibration

        plot_calibration(cal, args.plot)
    if args.json:
        print(json.dumps(msg.model_dump(mode="json")))
    else:
        print(to_yaml(msg), end="")
    return 0 if cal.passes else 1


def run_service(args: argparse.Namespace) -> int:
    from .service import main

    return main(args)
