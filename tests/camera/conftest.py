"""Fixtures of the camera tests: a software-device D435 fed by the project's ray caster."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_camera.correction import DepthCorrection
from sofia_camera.intrinsics import d435_spec
from sofia_camera.pipeline import CloudPipeline
from sofia_camera.processing import FilterChain
from sofia_camera.sim import SimRenderer
from sofia_camera.sim_scene import SimOptions, SimWorld
from sofia_camera.software import SoftwareCamera
from sofia_replay.synth.camera import look_at
from sofia_schemas.transforms import invert

BOARD_SEED = 3


def flange_above(world: SimWorld, height: float = 0.45) -> np.ndarray:
    """(4, 4) T_base_flange whose camera looks down at the scene's object (or blob) from ``height``."""
    truth = world.truth()
    target = np.array(truth["objects"][0]["center"] if "objects" in truth else truth["blob"]["p_base"])
    T_base_cam = look_at(target + np.array([0.03, -0.02, height]), target, np.array([0.0, 1.0, 0.0]))
    return T_base_cam @ invert(world.options.T_flange_cam)


@pytest.fixture(scope="session")
def board_world() -> SimWorld:
    return SimWorld(SimOptions(scene="board", seed=BOARD_SEED, noise=False))


class Rig:
    """A software D435 of one mode, the renderer of a world, and the cloud pipeline."""

    def __init__(self, world: SimWorld, width: int, height: int, filters: tuple[str, ...] = ()) -> None:
        self.spec = d435_spec(width, height)
        self.camera = SoftwareCamera(self.spec)
        self.renderer = SimRenderer(world, self.spec)
        self.correction = DepthCorrection()
        self.pipeline = CloudPipeline(FilterChain(filters), self.correction, max_skew_ms=16.0)
        self.camera.open()

    def close(self) -> None:
        self.camera.close()


@pytest.fixture
def make_rig():  # type: ignore[no-untyped-def]
    rigs: list[Rig] = []

    def make(world: SimWorld, width: int = 640, height: int = 480, filters: tuple[str, ...] = ()) -> Rig:
        rigs.append(Rig(world, width, height, filters))
        return rigs[-1]

    yield make
    for rig in rigs:
        rig.close()
