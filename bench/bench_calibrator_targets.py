"""Calibration per data set and target: ours vs the best off-the-shelf baseline, measured in one run.

Per data set: the leave-one-out error (real sets: every fold refitted) or the error to the truth
(synthetic), the correction chosen, the translation 1-sigma coverage, the time per calibration, and
the same for the baseline: ``scipy.optimize.least_squares`` on the point objective (rigid, from the
same closed-form start) for points, OpenCV's best ``calibrateHandEye`` method for pose targets.
Then the translation coverage and false outliers under noise the solver does not assume, the
model choice on small subsets of the lab set, and the depth scale of an earlier calibration used
as a prior (lab subsets; a synthetic camera re-mounted, its scale kept or moved).

Data: ``data/lab`` (the lab's 11 real samples, shipped); RegHEC's real sphere set (not shipped:
``--reghec DIR``, a checkout of github.com/Shiyu-Xing/RegHEC); handeye_calib_camodocal's 42 real
pose pairs (not shipped: ``--camodocal DIR``, a checkout of github.com/jhu-lcsr/handeye_calib_camodocal).
Rows whose data is absent say so.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from time import perf_counter as clock

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation
from sofia_calibrator import calibrate, read_lab
from sofia_calibrator.eye_to_hand import SETUPS, calibrate_eye_to_hand, calibrate_setup, flange_base_poses
from sofia_calibrator.fitting.diagnostics import error6
from sofia_calibrator.fitting.simulate import (
    UNMODELLED_NOISE,
    ball_cloud,
    make_eye_to_hand,
    make_problem,
    unmodelled_eye_to_hand,
    unmodelled_problem,
)
from sofia_calibrator.fitting.solver import linear_init
from sofia_calibrator.targets import find_sphere, read_cloud, read_euler_poses, shared_spheres, sphere_centres
from sofia_calibrator.targets.files import read_opencv_pose_pairs
from sofia_calibrator.targets.poses import consistency, hand_eye_from_poses

LAB = Path(__file__).resolve().parents[1] / "data" / "lab"


def ls_baseline(p_cam: np.ndarray, T: np.ndarray) -> np.ndarray:
    """(4, 4) T_flange_cam by least_squares on the point objective (mapped blob minus a free
    p_base, base frame), rigid, from the closed-form start."""
    R0, t0, p0 = linear_init(p_cam, T[:, :3, :3], T[:, :3, 3], np.ones(len(p_cam)))

    def f(x: np.ndarray) -> np.ndarray:
        R = Rotation.from_rotvec(x[:3]).as_matrix()
        m = np.einsum("nij,nj->ni", T[:, :3, :3], p_cam @ R.T + x[3:6]) + T[:, :3, 3]
        return np.asarray((m - x[6:9]).ravel())

    x = least_squares(f, np.r_[Rotation.from_matrix(R0).as_rotvec(), t0, p0]).x
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = Rotation.from_rotvec(x[:3]).as_matrix(), x[3:6]
    return out


def held_out_mm(T_fc: np.ndarray, apply, p: np.ndarray, T: np.ndarray, p_base: np.ndarray) -> float:  # type: ignore[no-untyped-def]
    m = np.einsum("ij,j->i", T[:3, :3], T_fc[:3, :3] @ apply(p) + T_fc[:3, 3]) + T[:3, 3]
    return float(1e3 * np.linalg.norm(m - p_base))


def real_points(name: str, p_cam: np.ndarray, T: np.ndarray, extra_s: float = 0.0) -> list[str]:
    """Refitted leave-one-out of ours and of the least-squares baseline on a real point set."""
    ours, base, models = [], [], []
    calibrate(p_cam, T)  # warm-up: the compiled kernels load once
    t0 = clock()
    for i in range(len(p_cam)):
        k = np.delete(np.arange(len(p_cam)), i)
        cal = calibrate(p_cam[k], T[k], leave_one_out=False)
        models.append(cal.correction.model)
        corr = cal.correction
        ours.append(
            held_out_mm(cal.T_flange_cam, lambda q, c=corr: c.apply(q[None])[0], p_cam[i], T[i], cal.p_base)
        )
    t_ours = (clock() - t0) / len(p_cam)
    t0 = clock()
    for i in range(len(p_cam)):
        k = np.delete(np.arange(len(p_cam)), i)
        X = ls_baseline(p_cam[k], T[k])
        mapped = np.einsum("nij,nj->ni", T[k, :3, :3], p_cam[k] @ X[:3, :3].T + X[:3, 3]) + T[k, :3, 3]
        base.append(held_out_mm(X, lambda q: q, p_cam[i], T[i], mapped.mean(axis=0)))
    t_base = (clock() - t0) / len(p_cam)
    full = calibrate(p_cam, T)
    rms = [float(np.sqrt(np.mean(np.square(x)))) for x in (ours, base)]
    kinds = ", ".join(f"{m} {models.count(m)}/{len(models)}" for m in sorted(set(models)))
    return [f"| {name} | LOO {rms[0]:.2f} mm | {full.correction.model} {full.correction.depth_scale:.4f} "
            f"(folds: {kinds}) | - | {1e3 * (t_ours + extra_s):.1f} ms | LOO {rms[1]:.2f} mm, "
            f"{1e3 * t_base:.1f} ms | {rms[1] / rms[0]:.2f}x |"]  # fmt: skip


def synthetic_points(name: str, make, trials: int, eye_to_hand: bool) -> str:  # type: ignore[no-untyped-def]
    """Truth error, correction chosen, coverage, time: ours vs the least-squares baseline."""
    e_o, e_b, cover, scaled, t_o, t_b = [], [], [], 0, 0.0, 0.0
    for k in range(trials):
        X_true, p_cam, T, biased = make(k)
        t0 = clock()
        cal = (calibrate_eye_to_hand if eye_to_hand else calibrate)(p_cam, T, leave_one_out=False)
        t_o += clock() - t0
        e = error6(cal.T_flange_cam, X_true)
        e_o.append(np.linalg.norm(e[:3]))
        cover.append(np.abs(e[:3]) <= np.sqrt(np.diag(cal.covariance6))[:3])
        scaled += (cal.correction.model != "rigid") == biased
        t0 = clock()
        Xb = ls_baseline(p_cam, flange_base_poses(T) if eye_to_hand else T)
        t_b += clock() - t0
        e_b.append(np.linalg.norm(error6(Xb, X_true)[:3]))
    r = [1e3 * float(np.sqrt(np.mean(np.square(x)))) for x in (e_o, e_b)]
    return (f"| {name} ({trials} sets) | truth {r[0]:.2f} mm | right model {100 * scaled / trials:.0f} % | "
            f"{100 * np.mean(cover):.1f} % | {1e3 * t_o / trials:.1f} ms | truth {r[1]:.2f} mm, "
            f"{1e3 * t_b / trials:.1f} ms | {r[1] / r[0]:.2f}x |")  # fmt: skip


def synthetic_poses(name: str, trials: int, setup: str, rng: np.random.Generator) -> str:
    e_o, e_b, cover, t_o = [], [], [], 0.0
    for _ in range(trials):
        pr = make_problem(12, rng, noise_scale=0.0)
        Y = np.eye(4)
        Y[:3, :3], Y[:3, 3] = Rotation.random(random_state=rng).as_matrix(), pr.p_base
        A = pr.T_base_flange
        B = np.linalg.inv(pr.T_flange_cam) @ np.linalg.inv(A) @ Y
        B[:, :3, :3] = (
            Rotation.from_rotvec(np.radians(0.3) * rng.standard_normal((12, 3))).as_matrix() @ B[:, :3, :3]
        )
        B[:, :3, 3] += rng.standard_normal((12, 3)) * 0.001
        A_in = np.linalg.inv(A) if setup == "eye-to-hand" else A  # the same views as the other set-up
        t0 = clock()
        fit = hand_eye_from_poses(A_in, B, setup=setup)
        t_o += clock() - t0
        e = error6(fit.X, pr.T_flange_cam)
        e_o.append(np.linalg.norm(e[:3]))
        cover.append(np.abs(e[:3]) <= fit.std_translation_mm / 1e3)
        e_b.append(min(np.linalg.norm(error6(X, pr.T_flange_cam)[:3]) for X in fit.baselines.values()))
    r = [1e3 * float(np.sqrt(np.mean(np.square(x)))) for x in (e_o, e_b)]
    return (f"| {name} ({trials} sets, 0.3 deg + 1 mm pose noise) | truth {r[0]:.2f} mm | - | "
            f"{100 * np.mean(cover):.1f} % | {1e3 * t_o / trials:.0f} ms (all 7 OpenCV starts: calibrateHandEye and calibrateRobotWorldHandEye) | "
            f"best OpenCV method per set: truth {r[1]:.2f} mm | {r[1] / r[0]:.2f}x |")  # fmt: skip


def coverage_table(sets: int, seed: int) -> None:
    """Translation coverage and false outliers under noise the solver does not assume, eye-in-hand
    and eye-to-hand, ``sets`` per cell; each cell's generator is ``default_rng([seed, n, kind
    index, set-up index])`` (tests/calibrator/test_noise.py uses seed 36)."""
    print(
        "| set-up | noise the solver does not assume | n | translation within 1-sigma | within 2-sigma | "
        "sets with a false outlier |"
    )
    print("|---|---|---|---|---|---|")
    for s, setup in enumerate(SETUPS):
        for k, kind in enumerate(UNMODELLED_NOISE):
            for n in (6, 11, 20, 50):
                rng = np.random.default_rng([seed, n, k, s])
                a1, a2, fa = [], [], 0
                for _ in range(sets):
                    if setup == "eye-to-hand":
                        eth = unmodelled_eye_to_hand(kind, n, rng)
                        p_cam, T, truth = eth.p_cam, eth.T_base_flange, eth.T_base_cam
                    else:
                        eih = unmodelled_problem(kind, n, rng)
                        p_cam, T, truth = eih.p_cam, eih.T_base_flange, eih.T_flange_cam
                    cal = calibrate_setup(p_cam, T, setup, leave_one_out=False, enforce_criterion=False)
                    e = np.abs(error6(cal.T_flange_cam, truth)[:3])
                    sd = np.sqrt(np.diag(cal.covariance6))[:3]
                    a1.append(e <= sd)
                    a2.append(e <= 2 * sd)
                    fa += bool(cal.outliers)
                print(f"| {setup} | {kind} | {n} | {100 * np.mean(a1):.1f} % | {100 * np.mean(a2):.1f} % | "
                      f"{100 * fa / sets:.1f} % |")  # fmt: skip


def synthetic_radius(trials: int, rng: np.random.Generator) -> str:
    """Sphere centres with the radius unknown: one shared radius (joint, median) vs a radius per
    view vs the radius given, on synthetic 25 mm balls at 0.45-0.9 m (10 views per set)."""
    inlier_m = 2.5e-3 * (0.9 / 0.5) ** 2
    err: dict[str, list[float]] = {"joint": [], "median": [], "per view": [], "given": []}
    for _ in range(trials):
        truth = np.c_[rng.uniform(-0.12, 0.12, (10, 2)), rng.uniform(0.45, 0.9, 10)]
        clouds = [ball_cloud(c, 0.025, rng) for c in truth]
        fits = {"joint": shared_spheres(clouds, inlier_m), "median": shared_spheres(clouds, inlier_m, "median"),
                "per view": [find_sphere(c, None, inlier_m) for c in clouds],
                "given": [find_sphere(c, 0.025, inlier_m) for c in clouds]}  # fmt: skip
        for k, spheres in fits.items():
            err[k] += list(np.linalg.norm([s.p_cam for s in spheres] - truth, axis=1))
    rms = ", ".join(f"{k} {1e3 * np.sqrt(np.mean(np.square(v))):.2f} mm" for k, v in err.items())
    return f"| synthetic ball of unknown radius, centre error RMS ({trials} sets of 10 views): {rms} | - | - | - | - | - | - |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reghec", type=Path, help="checkout of RegHEC (data/Sphere)")
    ap.add_argument("--camodocal", type=Path, help="checkout of handeye_calib_camodocal (example/)")
    ap.add_argument("--trials", type=int, default=100, help="synthetic sets per row")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--coverage-sets", type=int, help="sets per coverage cell (default: 2x --trials)")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print("| data set | ours: error | correction chosen | 1-sigma coverage (translation) | ours: time | "
          "baseline: error, time | baseline / ours |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    p_cam, T = read_lab(LAB / "poses.txt", LAB / "tfs.txt")
    for line in real_points("lab: 11 real blob samples, eye-in-hand (data/lab)", p_cam, T):
        print(line)
    sphere = args.reghec / "data" / "Sphere" if args.reghec else None
    if sphere and (sphere / "RobotPoses.dat").is_file():
        clouds = [read_cloud(sphere / f"view{i}d.pcd") for i in range(1, 10)]
        t0 = clock()
        centres = sphere_centres(clouds)[0]
        per_view = (clock() - t0) / 9
        Ts = read_euler_poses(sphere / "RobotPoses.dat")
        rms = float(np.sqrt(np.mean(calibrate(centres, Ts).residuals_mm ** 2)))
        radius = {"radius per view": [find_sphere(c).p_cam for c in clouds],
                  "radius given 48.4 mm": [find_sphere(c, 0.0484).p_cam for c in clouds]}  # fmt: skip
        radius_rms = ", ".join(f"{k}: {np.sqrt(np.mean(calibrate(np.array(v), Ts).residuals_mm ** 2)):.3f} mm"
                               for k, v in radius.items())  # fmt: skip
        print(
            f"| RegHEC sphere: fit RMS with one shared fitted radius {rms:.3f} mm; {radius_rms} | - | - | - | - | - | - |"
        )
        for line in real_points(f"RegHEC: 9 real sphere views, eye-in-hand (RegHEC data/Sphere; fit RMS {rms:.2f} mm; "
                                f"sphere fit {1e3 * per_view:.0f} ms/view, in the time)", centres, Ts, per_view * 8):  # fmt: skip
            print(line)
    else:
        print("| RegHEC sphere set | not present (--reghec DIR) | - | - | - | - | - |")
    print(synthetic_radius(max(2, args.trials // 8), np.random.default_rng(args.seed + 5)))
    pairs = args.camodocal / "example" / "TransformPairsInput.yml" if args.camodocal else None
    if pairs and pairs.is_file():
        T1, T2 = read_opencv_pose_pairs(pairs)
        t0 = clock()
        fit = hand_eye_from_poses(T1, T2, setup="eye-to-hand")
        t = clock() - t0
        ours = consistency(T1, T2, fit.X, "eye-to-hand")
        name, X = min(fit.baselines.items(), key=lambda kv: consistency(T1, T2, kv[1], "eye-to-hand")[0])
        base = consistency(T1, T2, X, "eye-to-hand")
        print(f"| camodocal: 42 real robot/marker pose pairs, eye-to-hand (example/TransformPairsInput.yml) | "
              f"target pose RMS {1e3 * ours[0]:.2f} mm / {np.degrees(ours[1]):.2f} deg | - | - | {1e3 * t:.0f} ms | "
              f"OpenCV {name}: {1e3 * base[0]:.2f} mm / {np.degrees(base[1]):.2f} deg | {base[0] / ours[0]:.2f}x |")  # fmt: skip
    else:
        print("| camodocal pose pairs | not present (--camodocal DIR) | - | - | - | - | - |")

    def eih(ds: float):  # type: ignore[no-untyped-def]
        def make(k: int):  # type: ignore[no-untyped-def]
            s = ds if ds != 0 else (0.96 if k % 2 else 1.0)
            pr = make_problem(12, rng, robot_noise_m=0.0015, depth_scale=s)
            return pr.T_flange_cam, pr.p_cam, pr.T_base_flange, s != 1.0

        return make

    def eth(k: int):  # type: ignore[no-untyped-def]
        s = 0.96 if k % 2 else 1.0
        pr = make_eye_to_hand(12, rng, robot_noise_m=0.001, depth_scale=s)
        return pr.T_base_cam, pr.p_cam, pr.T_base_flange, s != 1.0

    print(
        synthetic_points("synthetic blob, eye-in-hand, 12 poses, rigid camera", eih(1.0), args.trials, False)
    )
    print(
        synthetic_points(
            "synthetic blob, eye-in-hand, 12 poses, depth 4 % long", eih(0.96), args.trials, False
        )
    )
    print(
        synthetic_points(
            "synthetic ball, eye-to-hand, 12 poses, half with depth 4 % long", eth, args.trials, True
        )
    )
    print(
        synthetic_poses("synthetic pose target, eye-in-hand", max(args.trials // 4, 10), "eye-in-hand", rng)
    )
    print(
        synthetic_poses("synthetic pose target, eye-to-hand", max(args.trials // 4, 10), "eye-to-hand", rng)
    )
    print()
    coverage_table(args.trials * 2 if args.coverage_sets is None else args.coverage_sets, args.seed)
    print()
    subsets = min(40, 4 * args.trials)
    full = calibrate(p_cam, T).correction
    print(
        f"| lab subsets (data/lab), {subsets} random per size | held-out RMS: default | rigid | depth_scale always "
        "| prior: the full set's scale |"
    )
    print("|---|---|---|---|---|")
    for m in (6, 7, 8):
        errs: dict[str, list[float]] = {"auto": [], "rigid": [], "depth_scale": [], "prior": []}
        for _ in range(subsets):
            k = np.sort(rng.choice(11, m, replace=False))
            h = np.setdiff1d(np.arange(11), k)
            for corr, out in errs.items():
                kw = (
                    {"depth_scale_prior": (full.depth_scale, full.depth_scale_sigma)}
                    if corr == "prior"
                    else {}
                )
                cal = calibrate(p_cam[k], T[k], leave_one_out=False, correction="auto" if kw else corr, **kw)
                out.extend(1e3 * np.linalg.norm(cal.map_to_base(p_cam[h], T[h]) - cal.p_base, axis=1))
        r = {c: float(np.sqrt(np.mean(np.square(v)))) for c, v in errs.items()}
        print(
            f"| {m} samples | {r['auto']:.2f} mm | {r['rigid']:.2f} mm | {r['depth_scale']:.2f} mm | {r['prior']:.2f} mm |"
        )
    print()
    remount_table(max(args.trials, 50), args.seed)


def remount_table(trials: int, seed: int) -> None:
    """A camera calibrated once (11 synthetic views), then on a new mount from n views, with the
    first calibration's depth scale as the prior: RMS translation error over the plain ML fit of
    the true model, by default and with the prior."""
    print(
        f"| synthetic re-mount, {trials} sets per n | depth scale then -> now | n | default / ML | prior / ML |"
    )
    print("|---|---|---|---|---|")
    for s_then, s_now in ((1.0, 1.0), (0.96, 0.96), (0.95, 0.96), (0.95, 0.97)):
        for n in (6, 11, 20):
            rng = np.random.default_rng([seed, n, int(1000 * s_now)])
            errs: dict[str, list[float]] = {"auto": [], "prior": [], "ml": []}
            for _ in range(trials):
                e = make_problem(11, rng, robot_noise_m=0.0015, depth_scale=s_then)
                then = calibrate(
                    e.p_cam, e.T_base_flange, leave_one_out=False, correction="depth_scale"
                ).correction
                pr = make_problem(n, rng, robot_noise_m=0.0015, depth_scale=s_now)
                for name, kw in (("auto", {}), ("prior", {"depth_scale_prior": (then.depth_scale, then.depth_scale_sigma)}),
                                 ("ml", {"correction": "rigid" if s_now == 1.0 else "depth_scale"})):  # fmt: skip
                    cal = calibrate(pr.p_cam, pr.T_base_flange, leave_one_out=False, **kw)  # type: ignore[arg-type]
                    errs[name].append(float(np.linalg.norm(cal.translation - pr.T_flange_cam[:3, 3])))
            r = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errs.items()}
            print(f"| | {s_then} -> {s_now} | {n} | {r['auto'] / r['ml']:.3f} | {r['prior'] / r['ml']:.3f} |")


if __name__ == "__main__":
    main()
