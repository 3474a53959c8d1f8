"""Force estimate of the gripper, and its calibration against a scale.

The service reports ``force_n = current_ma / 1000 * force_per_amp_n``. The default 25 N/A is a
model estimate: the MX-64's torque constant from its e-Manual stall figures (6.0 N m at 4.1 A,
about 1.46 N m/A), through the 20 mm crank (about 73 N/A on the slider with the crank at right
angles), divided by about 3 for the Fin-Ray fingers' transmission from slider to fingertip. The
fingers' stiffness, friction in the slider and where the object sits along the fingers change
that factor, so a lab measures it: :func:`calibrate_force` grasps a kitchen scale (or a force
gauge) at several currents, takes what the scale reads, fits the force per ampere through the
origin (least squares) and writes it into the gripper config.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .config import GripperConfig, save_config
from .errors import ConfigError

log = logging.getLogger(__name__)
G_N_PER_KG = 9.80665


def parse_reading(text: str) -> float:
    """A scale reading in newtons from ``'1250'`` / ``'1250 g'`` (grams), ``'1.2 kg'`` or ``'12 N'``."""
    t = text.strip().lower().replace(",", ".")
    units = {"kg": G_N_PER_KG, "g": G_N_PER_KG / 1000, "n": 1.0}
    factor = units["g"]
    for suffix in ("kg", "g", "n"):
        if t.endswith(suffix):
            t, factor = t[: -len(suffix)].strip(), units[suffix]
            break
    try:
        value = float(t)
    except ValueError:
        raise ConfigError(
            f"scale reading {text.strip()!r} is not a number (e.g. 1250 g, 1.2 kg, 12 N)"
        ) from None
    if not np.isfinite(value) or value <= 0:
        raise ConfigError(f"scale reading {text.strip()!r} must be a positive number")
    return value * factor


def fit_force_per_amp(currents_ma: Sequence[float], forces_n: Sequence[float]) -> tuple[float, float]:
    """Least-squares force per ampere through the origin, and the RMS residual (N).

    ``currents_ma``: (n,) measured motor currents while squeezing, mA; ``forces_n``: (n,) forces.
    """
    amps = np.asarray(currents_ma, float) / 1000.0
    forces = np.asarray(forces_n, float)
    if amps.shape != forces.shape or amps.size < 2 or not np.all(amps > 0):
        raise ConfigError(f"need at least 2 positive currents with one force each, got {amps.size}")
    k = float(amps @ forces / (amps @ amps))
    rms = float(np.sqrt(np.mean((forces - k * amps) ** 2)))
    return k, rms


def calibrate_force(
    config: GripperConfig,
    out: Path,
    currents_ma: Sequence[float],
    ask: Callable[[str], str] = input,
    say: Callable[[str], None] = print,
) -> GripperConfig:
    """Grasp a scale at each of ``currents_ma``, read it, fit and save ``force_per_amp_n``."""
    from sofia_schemas.messages import GripperCommand

    from .commands import Gripper

    g = Gripper(config)
    g.start()
    deadline = time.monotonic() + 5.0
    while not g.connected and time.monotonic() < deadline:
        time.sleep(0.05)
    measured: list[float] = []
    forces: list[float] = []
    try:
        if not g.connected:
            raise ConfigError(f"no MX-64 answered on {config.port}: {g.error}")
        say("Put a kitchen scale (or force gauge) between the fingertips, where objects are held.")
        ask("Press Enter when it is in place: ")
        for current in currents_ma:
            r = g.execute(GripperCommand(action="grasp", current_ma=current, speed=0.3, timeout_s=15))
            if not (r.ok and r.grasped and r.state and r.state.current_ma):
                raise ConfigError(f"grasp at {current:g} mA did not stall on the scale: {r.reason}")
            measured.append(float(r.state.current_ma))
            forces.append(parse_reading(ask(f"{current:g} mA: scale reading (g, or with kg / N): ")))
            g.execute(GripperCommand(action="open", timeout_s=15))
    finally:
        g.close()
    k, rms = fit_force_per_amp(measured, forces)
    new = GripperConfig.model_validate({**config.model_dump(), "force_per_amp_n": k})
    save_config(new, out)
    say(
        f"force per ampere {k:.2f} N/A (was {config.force_per_amp_n:g}), RMS residual {rms:.2f} N; saved {out}"
    )
    log.info("force calibration: %s N/A from %s mA / %s N", k, measured, forces)
    return new
