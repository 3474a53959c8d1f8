"""The depth scale of an earlier calibration of the same camera as a prior: small real sets predict
their held-out samples better, an exact camera stays exact, a camera whose scale moved is not held
to the old one, the 1-sigma keeps its coverage, and bad priors get one clear line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sofia_calibrator import calibrate, read_lab
from sofia_calibrator.errors import InputMismatch
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.result_files import read_scale_prior

SOFIA = str(Path(sys.executable).with_name("sofia"))


def _rms(x: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _held_out_mm(cal, p_cam: np.ndarray, T_base_flange: np.ndarray) -> list[float]:  # type: ignore[no-untyped-def]
    return list(1e3 * np.linalg.norm(cal.map_to_base(p_cam, T_base_flange) - cal.p_base, axis=1))


def test_a_prior_from_the_other_lab_samples_helps_a_small_set_predict_its_own(lab_dir: Path) -> None:
    # no sample is both in the prior and predicted: each 6-sample subset's leave-one-out folds
    # (5 samples) take the scale fitted on the 5 samples outside the subset
    p, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    rng = np.random.default_rng(0)
    auto, prior = [], []
    for _ in range(25):
        k = np.sort(rng.choice(11, 6, replace=False))
        h = np.setdiff1d(np.arange(11), k)
        earlier = calibrate(p[h], T[h], correction="depth_scale", leave_one_out=False).correction
        for i in range(6):
            kk = np.delete(k, i)
            for out, kw in (
                (auto, {}),
                (prior, {"depth_scale_prior": (earlier.depth_scale, earlier.depth_scale_sigma)}),
            ):
                out += _held_out_mm(
                    calibrate(p[kk], T[kk], leave_one_out=False, **kw), p[k[i] : k[i] + 1], T[k[i]]
                )  # type: ignore[arg-type]
    assert _rms(prior) < 0.7 * _rms(auto), (_rms(prior), _rms(auto))  # measured 4.05 vs 5.97 mm


def test_the_full_sets_scale_helps_every_small_subset(lab_dir: Path) -> None:
    p, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    full = calibrate(p, T).correction
    rng = np.random.default_rng(0)
    for m in (6, 7, 8):
        errs: dict[str, list[float]] = {"auto": [], "depth_scale": [], "prior": []}
        for _ in range(25):
            k = np.sort(rng.choice(11, m, replace=False))
            h = np.setdiff1d(np.arange(11), k)
            for name, out in errs.items():
                kw = (
                    {"depth_scale_prior": (full.depth_scale, full.depth_scale_sigma)}
                    if name == "prior"
                    else {"correction": name}
                )
                out += _held_out_mm(calibrate(p[k], T[k], leave_one_out=False, **kw), p[h], T[h])  # type: ignore[arg-type]
        r = {name: _rms(v) for name, v in errs.items()}
        assert r["prior"] < r["auto"] and r["prior"] < r["depth_scale"], (m, r)


def _remount(
    n: int, s_before: float, s_now: float, trials: int, seed: int
) -> tuple[float, float, float, list[str]]:
    """An earlier 11-view calibration of a camera whose depth reads 1 / s_before long, then n views of
    it on a new mount (its depth now 1 / s_now long): RMS translation error (mm) with the prior, by
    default, and of the plain ML fit of the true model; the reasons given with the prior."""
    rng = np.random.default_rng(seed)
    errs: dict[str, list[float]] = {"prior": [], "auto": [], "ml": []}
    reasons = []
    for _ in range(trials):
        e = make_problem(11, rng, robot_noise_m=0.0015, depth_scale=s_before)
        earlier = calibrate(
            e.p_cam, e.T_base_flange, leave_one_out=False, correction="depth_scale"
        ).correction
        pr = make_problem(n, rng, robot_noise_m=0.0015, depth_scale=s_now)
        for name, kw in (("prior", {"depth_scale_prior": (earlier.depth_scale, earlier.depth_scale_sigma)}), ("auto", {}),
                         ("ml", {"correction": "rigid" if s_now == 1.0 else "depth_scale"})):  # fmt: skip
            cal = calibrate(pr.p_cam, pr.T_base_flange, leave_one_out=False, **kw)  # type: ignore[arg-type]
            errs[name].append(1e3 * float(np.linalg.norm(cal.translation - pr.T_flange_cam[:3, 3])))
            if name == "prior":
                reasons.append(cal.correction_reason)
    return _rms(errs["prior"]), _rms(errs["auto"]), _rms(errs["ml"]), reasons


def test_a_remounted_camera_is_calibrated_from_few_views() -> None:
    for n in (6, 11, 20):
        prior, auto, ml, _ = _remount(n, 0.96, 0.96, 100, n)
        assert prior < auto and prior <= 1.0 * ml, (n, prior, auto, ml)  # measured 0.82-0.97x the ML fit


def test_an_exact_camera_stays_exact_with_a_prior() -> None:
    for n in (6, 11, 20):
        prior, _, ml, reasons = _remount(n, 1.0, 1.0, 100, 10 + n)
        assert prior <= 1.05 * ml, (n, prior, ml)
        assert sum(r.startswith("depth_scale: prior") for r in reasons) <= 5, reasons


def test_a_camera_whose_scale_moved_is_not_held_to_the_old_one() -> None:
    pr = make_problem(20, np.random.default_rng(3), robot_noise_m=0.0015, depth_scale=1.0)
    cal = calibrate(pr.p_cam, pr.T_base_flange, depth_scale_prior=(0.90, 0.005))
    assert cal.correction.model == "rigid", cal.correction_reason
    assert "prior is not used" in cal.correction_reason, cal.correction_reason
    assert 1e3 * np.linalg.norm(cal.translation - pr.T_flange_cam[:3, 3]) < 10.0


def test_the_one_sigma_with_a_prior_keeps_its_coverage() -> None:
    z = []
    rng = np.random.default_rng([36, 1])
    for n in (6, 11):
        for _ in range(150):
            e = make_problem(11, rng, robot_noise_m=0.0015, depth_scale=0.96)
            earlier = calibrate(
                e.p_cam, e.T_base_flange, leave_one_out=False, correction="depth_scale"
            ).correction
            pr = make_problem(n, rng, robot_noise_m=0.0015, depth_scale=0.96)
            cal = calibrate(pr.p_cam, pr.T_base_flange, leave_one_out=False,
                            depth_scale_prior=(earlier.depth_scale, earlier.depth_scale_sigma))  # fmt: skip
            assert cal.correction_reason.startswith("depth_scale: prior"), cal.correction_reason
            z.extend(np.abs(cal.translation - pr.T_flange_cam[:3, 3]) / (1e-3 * cal.std_translation_mm))
    within1, within2 = 100 * np.mean(np.array(z) < 1), 100 * np.mean(np.array(z) < 2)
    # targets 62-74 % and 92-98 %, widened by about 3 sigma of 900 axis-trials (measured 73 / 97 %)
    assert 58 <= within1 <= 78 and 90 <= within2 <= 99, (within1, within2)


def test_bad_priors_get_one_clear_line(tmp_path: Path, lab_dir: Path) -> None:
    p, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    for prior, kw, words in (((0.95, 0.01), {"correction": "rigid"}, "needs correction"),
                             ((float("nan"), 0.01), {}, "prior depth scale"), ((0.95, -1.0), {}, "sigma and drift"),
                             ("x", {}, "(scale, sigma)")):  # fmt: skip
        with pytest.raises(InputMismatch, match=words.replace("(", r"\(").replace(")", r"\)")):
            calibrate(p, T, depth_scale_prior=prior, **kw)  # type: ignore[arg-type]
    rigid = tmp_path / "rigid.yaml"
    rigid.write_text("camera_correction:\n  model: rigid\n")
    with pytest.raises(InputMismatch, match="no fitted depth scale"):
        read_scale_prior(rigid)
    (tmp_path / "list.yaml").write_text("- 1\n")
    with pytest.raises(InputMismatch, match="not a calibration result"):
        read_scale_prior(tmp_path / "list.yaml")


def test_the_command_takes_an_earlier_result(tmp_path: Path, lab_dir: Path) -> None:
    lab = ["--poses", str(lab_dir / "poses.txt"), "--tfs", str(lab_dir / "tfs.txt")]
    earlier = tmp_path / "earlier.yaml"
    assert (
        subprocess.run([SOFIA, "calibrate", *lab, "--yaml", str(earlier)], capture_output=True).returncode
        == 0
    )
    lines = (lab_dir / "tfs.txt").read_text().splitlines(keepends=True)
    (tmp_path / "p6.txt").write_text(
        "".join((lab_dir / "poses.txt").read_text().splitlines(keepends=True)[:6])
    )
    (tmp_path / "t6.txt").write_text("".join(lines[: 6 * 9]))
    six = ["--poses", str(tmp_path / "p6.txt"), "--tfs", str(tmp_path / "t6.txt")]
    out = subprocess.run(
        [SOFIA, "calibrate", *six, "--scale-prior", str(earlier)], capture_output=True, text=True
    )
    assert "prior 0.9494 +- 0.0085 from an earlier calibration" in out.stdout, out.stdout + out.stderr
    bad = subprocess.run(
        [SOFIA, "calibrate", *six, "--scale-prior", str(tmp_path / "p6.txt")], capture_output=True, text=True
    )
    assert bad.returncode == 2 and bad.stderr.strip().count("\n") == 0, bad.stderr
    assert "not a calibration result" in bad.stderr


def test_an_unused_prior_leaves_the_fit_as_without_one(lab_dir: Path) -> None:
    # a prior far from the data is not used: the result is the default's, on 5 samples (where the
    # scale is not tried) as on 11
    p, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    for k in (np.arange(5), np.arange(11)):
        plain = calibrate(p[k], T[k], leave_one_out=False)
        far = calibrate(p[k], T[k], leave_one_out=False, depth_scale_prior=(0.6, 0.001))
        assert "prior is not used" in far.correction_reason, far.correction_reason
        assert far.correction == plain.correction and np.array_equal(far.T_flange_cam, plain.T_flange_cam)
        assert np.array_equal(far.covariance, plain.covariance)
