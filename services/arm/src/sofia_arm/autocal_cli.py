"""``sofia calibrate auto``: ask the arm service to calibrate the camera by itself, print each pose
as it is taken and the result with its launch-file line.

Light on purpose (Zenoh and the schemas only): the calibrator's command line registers it.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from sofia_runtime.output import add_json_option, emit
from sofia_runtime.zenoh_config import ZenohOptions, add_zenoh_args, zenoh_config
from sofia_schemas.keys import Keys, add_robot_arg, default_robot


def register_auto(calibrate_parser: argparse.ArgumentParser) -> None:
    """Add ``auto`` under ``sofia calibrate``."""
    sub = calibrate_parser.add_subparsers(dest="calibrate_mode", metavar="auto", required=False)
    a = sub.add_parser(
        "auto", help="autonomous calibration: the arm service shows the blob (or a ball) to the camera",
        description="The arm service plans views of the blob, visits them, feeds the calibrator and stops "
        "when the translation 1-sigma is below the target or the pose budget is spent.",
    )  # fmt: skip
    a.add_argument("--setup", choices=("eye-in-hand", "eye-to-hand"), default="eye-in-hand",
                   help="eye-in-hand: the camera on the flange, the blob on the table; eye-to-hand: a fixed "
                   "camera, a ball on the flange (default eye-in-hand)")  # fmt: skip
    a.add_argument("--target", choices=("blob", "ball"),
                   help="eye-in-hand: the blob (default) or a coloured ball on the table; eye-to-hand: a ball")  # fmt: skip
    a.add_argument("--blob", nargs=3, type=float, metavar=("X", "Y", "Z"),
                   help="rough target position, metres: the blob or ball in the base frame, or (eye-to-hand) "
                   "the ball in the flange frame (default: found from the start pose)")  # fmt: skip
    a.add_argument("--guess", nargs=7, type=float, metavar=("X", "Y", "Z", "QX", "QY", "QZ", "QW"),
                   help="rough T_flange_cam, or (eye-to-hand) T_base_cam (default: found from the start pose)")  # fmt: skip
    a.add_argument("--ball-radius", type=float, metavar="M",
                   help="the ball's radius, metres (default: fitted in each view)")  # fmt: skip
    a.add_argument("--target-mm", type=float, default=1.0, help="stop at this translation 1-sigma (mm)")
    a.add_argument("--max-poses", type=int, default=20, help="pose budget: most poses visited (default 20)")
    a.add_argument("--min-poses", type=int, default=6, help="poses taken before stopping early (default 6)")
    a.add_argument("--speed", type=float, default=0.2, help="relative speed (capped by the arm's limits)")
    a.add_argument("--timeout", type=float, default=600.0, help="seconds for the whole calibration")
    add_json_option(a, "the final ArmResult, one object; the poses as they are taken go to stderr")
    add_robot_arg(a)
    add_zenoh_args(a)
    a.set_defaults(func=run_auto)


def options(args: argparse.Namespace) -> dict[str, Any]:
    opts: dict[str, Any] = {"target_sigma_mm": args.target_mm, "max_poses": args.max_poses,
                            "min_poses": args.min_poses, "setup": args.setup}  # fmt: skip
    if args.target is not None:
        opts["target"] = args.target
    if args.ball_radius is not None:
        opts["ball_radius"] = args.ball_radius
    if args.blob:
        opts["blob"] = list(args.blob)
    if args.guess:
        opts["guess"] = list(args.guess)
    return opts


def run_auto(args: argparse.Namespace) -> int:
    import numpy as np
    import zenoh
    from sofia_runtime.client import QueryError, ask
    from sofia_schemas.messages import ArmCommand, ArmPhase, ArmResult

    keys = Keys(args.robot or default_robot())
    cmd = ArmCommand(command="calibrate", speed=args.speed, timeout_s=args.timeout, calibrate=options(args))

    def show(s: zenoh.Sample) -> None:
        try:
            p = ArmPhase.model_validate_json(s.payload.to_bytes())
        except ValueError:
            return
        print(p.line(), file=sys.stderr if args.json else sys.stdout, flush=True)

    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        sub = session.declare_subscriber(keys.arm_progress, show)
        try:
            res = ask(session, keys.arm_command, ArmResult, cmd.model_dump_json(), timeout=args.timeout + 30)
        except QueryError as e:
            print(f"calibrate auto: {e}", file=sys.stderr)
            return 1
        finally:
            sub.undeclare()
    if args.json:
        emit(args, res, "")
        return 0 if res.ok else 1
    r = res.details.get("result")
    print(f"{res.status}: {res.reason} ({res.details.get('samples', 0)} samples, {res.duration_s:.0f} s)")
    if r:
        print("T_base_cam (camera optical frame -> base, metres):" if args.setup == "eye-to-hand"
              else "T_flange_cam (camera optical frame -> flange, metres):")  # fmt: skip
        print(np.array2string(np.array(r["matrix"]), precision=4, suppress_small=True))
        print(f"  translation {np.round(r['translation'], 4).tolist()} m, quaternion x y z w "
              f"{np.round(r['quaternion_xyzw'], 4).tolist()}")  # fmt: skip
        sigma_t = res.details.get("sigma_translation_mm", r["std_translation_mm"])
        print(f"  1-sigma translation {np.round(sigma_t, 2).tolist()} mm (never below the noise model's), "
              f"rotation {np.round(r['std_rotation_deg'], 3).tolist()} deg")  # fmt: skip
        print(f"  ROS 1: {r.get('ros1_static_transform', '')}")
    return 0 if res.ok else 1
