"""``passes`` is a verdict the samples can support: false (and said to be undetermined) with no
redundancy or with a translation 1-sigma beyond the 1 cm criterion, whatever the spread shows."""

from __future__ import annotations

import numpy as np
from sofia_calibrator import to_message
from sofia_calibrator.fitting.calibrate import calibrate
from sofia_calibrator.fitting.simulate import make_problem


def test_three_samples_do_not_pass() -> None:
    prob = make_problem(3, np.random.default_rng(5))
    cal = calibrate(prob.p_cam, prob.T_base_flange, correction="rigid")
    assert max(cal.spread_mm) < 1e-6  # no redundancy: the fit goes through every sample
    assert not cal.passes and "no redundancy" in cal.undetermined
    msg = to_message(cal)
    assert msg.passes is False
    assert any(w.startswith("the lab criterion is undetermined (passes is false): 3 samples leave no redundancy")
               for w in msg.warnings), msg.warnings  # fmt: skip


def test_a_wide_uncertainty_does_not_pass_on_a_small_spread() -> None:
    """Four poses with 6x the camera's noise: the spread is within 1 cm, the 1-sigma is not."""
    prob = make_problem(4, np.random.default_rng(2), noise_scale=6.0)
    cal = calibrate(prob.p_cam, prob.T_base_flange, correction="rigid")
    assert max(cal.spread_mm) < 10.0 < max(cal.std_translation_mm), (cal.spread_mm, cal.std_translation_mm)
    assert not cal.passes and "1-sigma" in cal.undetermined


def test_a_well_posed_set_still_passes() -> None:
    prob = make_problem(12, np.random.default_rng(2))
    cal = calibrate(prob.p_cam, prob.T_base_flange)
    assert cal.passes and cal.undetermined == "" and max(cal.std_translation_mm) < 10.0
