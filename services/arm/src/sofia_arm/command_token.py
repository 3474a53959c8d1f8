"""The life of one arm command: cancelled once (stopped, preempted, timed out), with the reason."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

from sofia_schemas.messages import ArmCommandName, ArmStatus


@dataclass
class Token:
    """The life of one command: cancelled once, with a status and a reason."""

    command: ArmCommandName
    timeout_s: float
    started: float = field(default_factory=time.monotonic)
    status: ArmStatus | None = None
    reason: str = ""
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def cancel(self, status: ArmStatus, reason: str) -> None:
        with self._lock:
            if self.status is None:
                self.status, self.reason = status, reason

    def ended(self) -> bool:
        """True once cancelled (checks the deadline too)."""
        if self.status is None and time.monotonic() - self.started > self.timeout_s:
            self.cancel("timeout", f"{self.command} timed out after {self.timeout_s:g} s")
        return self.status is not None
