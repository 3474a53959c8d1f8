"""The gripper's bounded queue of motion commands, and the stop that empties it.

Motion commands run one at a time; at most ``depth`` wait behind the running one (more are refused
with :class:`~sofia_gripper.errors.QueueFull`). A ``stop`` ends the running command and answers
every queued one ``stopped`` without moving. A queued command's ``timeout_s`` counts from its
receipt: one that waited past it is answered ``expired`` without moving (its caller has given up),
and one that starts late gets only the rest of its time.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import zenoh
from sofia_runtime.service import reply_json
from sofia_schemas.messages import GripperCommand, GripperResult

from .commands import Gripper
from .errors import QueueFull

log = logging.getLogger(__name__)
QUEUE_DEPTH = 4  # motion commands waiting behind the running one
MIN_START_S = 0.05  # a command with less time left than this is expired rather than started


@dataclass
class Queued:
    query: zenoh.Query
    cmd: GripperCommand
    generation: int  # the stop count when it was queued: a later stop cancels it
    received: float  # time.monotonic() at receipt


class CommandQueue:
    """Bounded motion queue of ``gripper``; ``run`` executes one command and answers its query."""

    def __init__(
        self, gripper: Gripper, run: Callable[[zenoh.Query, GripperCommand], None], depth: int = QUEUE_DEPTH
    ) -> None:
        self.gripper, self.run, self.depth = gripper, run, depth
        self.items: queue.Queue[Queued | None] = queue.Queue(maxsize=depth)
        self.lock = threading.Lock()  # orders stops against the start of each command
        self.generation = 0
        self.counters = {"stopped": 0, "expired": 0, "queue_full": 0}

    def put(self, query: zenoh.Query, cmd: GripperCommand) -> None:
        """Queue ``cmd``; raises :class:`QueueFull` when ``depth`` commands already wait."""
        with self.lock:
            item = Queued(query, cmd, self.generation, time.monotonic())
        try:
            self.items.put_nowait(item)
        except queue.Full:
            self.counters["queue_full"] += 1
            raise QueueFull(self.depth) from None

    def stop(self) -> int:
        """Cancel the running command and every queued one (each answered ``stopped``); returns
        how many queued commands were cancelled. The caller then holds the fingers where they are."""
        with self.lock:
            self.generation += 1
            self.gripper.abort.set()
        cancelled = 0
        while True:
            try:
                item = self.items.get_nowait()
            except queue.Empty:
                break
            if item is None:  # the end of the loop: put it back for the worker
                self.items.put(None)
                break
            self._answer(item, "stopped", "stopped before it started: a stop command cancelled it")
            cancelled += 1
        return cancelled

    def close(self) -> None:
        """End :meth:`work_loop` after cancelling what waits."""
        self.stop()
        self.items.put(None)

    def work_loop(self) -> None:
        while (item := self.items.get()) is not None:
            with self.lock:
                if item.generation != self.generation:
                    self._answer(item, "stopped", "stopped before it started: a stop command cancelled it")
                    continue
                left_s = item.cmd.timeout_s - (time.monotonic() - item.received)
                if left_s < MIN_START_S:
                    self._answer(
                        item,
                        "expired",
                        f"expired: waited {item.cmd.timeout_s:g} s (its timeout_s) in the queue",
                    )
                    continue
                self.gripper.abort.clear()  # under the lock: a stop from here on ends this command
            self.run(item.query, item.cmd.model_copy(update={"timeout_s": left_s}))

    def _answer(self, item: Queued, counter: str, reason: str) -> None:
        self.counters[counter] += 1
        log.info("gripper %s %s", item.cmd.action, reason)
        state = self.gripper.state
        result = GripperResult(action=item.cmd.action, ok=False, reason=reason, opening_mm=state.opening_mm,
                               duration_s=time.monotonic() - item.received, state=state)  # fmt: skip
        reply_json(item.query, result)
