"""What compound commands (pick and place, autonomous calibration) may do with the arm.

The service hands each compound command an :class:`ArmMotion` bound to that command: its motions
obey the service's safety checks (workspace box, joint margins, speed limits, gripper errors) and
end early when the command is stopped, preempted or runs out of time. Once that happened, every
further ``move_*`` returns the same non-``done`` result at once and ``wait_still`` returns False,
so a compound command only has to stop at the first result that is not ``ok``.

Entry points the service calls (``sofia_arm.pick_place`` and ``sofia_arm.autocal``)::

    run_pick_place(cmd: ArmCommand, arm: ArmMotion, session: zenoh.Session, keys: Keys) -> ArmResult
    run_autocal(cmd: ArmCommand, arm: ArmMotion, session: zenoh.Session, keys: Keys) -> ArmResult
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from sofia_schemas.messages import ArmResult


@runtime_checkable
class ArmMotion(Protocol):
    """Motion and measurement of one arm, as seen by one command."""

    def move_joints(self, q_rad: np.ndarray, speed: float) -> ArmResult:
        """Move to joint positions ``q_rad`` (7,) rad; ``speed`` relative (0, 1], capped by the
        service's limits. Returns when the arm is there (``done``) or the motion ended otherwise
        (``stopped``, ``preempted``, ``failed`` with the reason, ``timeout``); never raises for a
        refused target: the result says ``failed`` and why."""
        ...

    def move_pose(self, T_base_flange: np.ndarray, speed: float) -> ArmResult:
        """Move the flange to ``T_base_flange`` (4, 4), base frame (``panda_link0``) ->
        flange (``panda_link8``), metres, in a straight Cartesian line; as :meth:`move_joints`."""
        ...

    def T_base_flange(self) -> np.ndarray:
        """The measured flange pose (4, 4), from the measured joints through the Panda kinematics."""
        ...

    def q(self) -> np.ndarray:
        """The measured joint positions (7,), rad."""
        ...

    def wait_still(self, timeout_s: float) -> bool:
        """Wait until the arm is at rest (joint speeds near zero); False on timeout, stop or
        preemption."""
        ...

    def stamp_ns(self) -> int:
        """Bus time (ns, the clock of published poses) of the latest robot state."""
        ...
