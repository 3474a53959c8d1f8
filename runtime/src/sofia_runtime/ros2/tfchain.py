"""The base -> flange pose from ROS 2 ``/tf``, composed along the chain of frames.

A robot state publisher sends one ``TransformStamped`` per joint (``panda_link0 -> panda_link1``,
..., ``panda_link7 -> panda_link8``), all with the stamp of one joint state. :class:`TfChain` keeps
the latest transform of every edge and, when a message touches the chain, composes
``T_base_flange = T_base_l1 @ T_l1_l2 @ ... @ T_l7_flange``, stamped with the newest stamp among
the message's transforms on the chain. A direct ``base -> flange`` transform works the same way.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sofia_schemas.messages import FlangePose
from sofia_schemas.transforms import make_transform

MAX_DEPTH = 64


class TfChain:
    def __init__(self, base_frame: str, flange_frame: str) -> None:
        self.base_frame, self.flange_frame = base_frame, flange_frame
        self.edges: dict[str, tuple[str, np.ndarray]] = {}  # child -> (parent, T_parent_child)

    def chain(self) -> list[str] | None:
        """Frames from the flange up to the base (flange first), None while incomplete."""
        frames, frame = [self.flange_frame], self.flange_frame
        while frame != self.base_frame:
            if frame not in self.edges or len(frames) > MAX_DEPTH:
                return None
            frame = self.edges[frame][0]
            frames.append(frame)
        return frames

    def update(self, transforms: list[Any]) -> FlangePose | None:
        """Take a ``tf2_msgs/msg/TFMessage``'s transforms; the flange pose when they touch the chain."""
        stamps: dict[str, int] = {}
        for t in transforms:
            tr, q = t.transform.translation, t.transform.rotation
            try:
                T = make_transform(np.array([tr.x, tr.y, tr.z]), np.array([q.x, q.y, q.z, q.w]))
            except ValueError:
                continue  # a bad quaternion: that edge keeps its previous value
            child = t.child_frame_id.lstrip("/")
            self.edges[child] = (t.header.frame_id.lstrip("/"), T)
            stamps[child] = int(t.header.stamp.sec) * 1_000_000_000 + int(t.header.stamp.nanosec)
        frames = self.chain()
        if frames is None:
            return None
        touched = [stamps[f] for f in frames[:-1] if f in stamps]
        if not touched:
            return None
        T_base_flange = np.eye(4)
        for child in reversed(frames[:-1]):  # from the base down to the flange
            T_base_flange = T_base_flange @ self.edges[child][1]
        return FlangePose.from_matrix(T_base_flange, max(touched), self.base_frame, self.flange_frame)
