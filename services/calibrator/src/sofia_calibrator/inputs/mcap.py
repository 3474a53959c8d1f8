"""Calibration samples from an MCAP recording: blob observations (or camera clouds, extracting the
blob or a coloured ball) paired with the recorded flange poses; a ball of unknown radius gets one
radius shared by every paired view (:func:`~sofia_calibrator.targets.sphere_shared.fit_shared`)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from sofia_schemas import rosmsg
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE

from ..errors import CalibrationError, InputMismatch
from ..pairing import NotPaired, PairingOptions, PoseBuffer
from ..targets.ball import CLOUD_TARGETS, find_target

log = logging.getLogger(__name__)


@dataclass
class McapSamples:
    p_cam: np.ndarray  # (n, 3) camera optical frame, metres
    T_base_flange: np.ndarray  # (n, 4, 4)
    stamps_ns: list[int]
    rejected: list[str] = field(default_factory=list)  # why each skipped observation was skipped
    radius_m: float | None = None  # a ball's radius fitted to all the views (None: given, or a blob)


def read_mcap(
    path: str | Path, from_clouds: bool = False, opts: PairingOptions | None = None,
    blob_topic: str = TOPIC_BLOB, pose_topic: str = TOPIC_FLANGE_POSE, cloud_topic: str = TOPIC_CAMERA_POINTS,
    target: str = "blob", radius_m: float | None = None,
) -> McapSamples:  # fmt: skip
    """Samples of a recording. ``from_clouds``: extract the target (``target``: ``blob``, or
    ``ball`` of ``radius_m`` metres, None: fitted) from the organized camera clouds instead of
    reading recorded blob observations."""
    if target not in CLOUD_TARGETS:
        raise InputMismatch(f"target must be one of {list(CLOUD_TARGETS)}, got {target!r}")
    from sofia_replay.mcap_io import iter_messages

    opts = opts or PairingOptions()
    poses = PoseBuffer()
    observations: list[tuple[int, np.ndarray]] = []
    segments: dict[int, tuple[np.ndarray, np.ndarray, float] | None] = {}  # a ball's view, by stamp
    rejected: list[str] = []
    topics = [pose_topic, cloud_topic if from_clouds else blob_topic]
    for m in iter_messages(path, topics):
        if m.topic == pose_topic:
            pose = rosmsg.decode_flange_pose(m.data)
            poses.add(pose.stamp_ns, pose.matrix())
        elif from_clouds:
            from sofia_schemas import pointcloud

            cloud = pointcloud.decode(m.data)
            try:
                xyz, rgb = cloud.xyz(), cloud.rgb()
                if rgb is None:
                    raise InputMismatch(
                        f"cloud on {cloud_topic!r} has no rgb field: the {target} cannot be found"
                    )
                shape = (cloud.height, cloud.width, 3)
                p_cam, _, segment = find_target(target, xyz.reshape(shape), rgb.reshape(shape), radius_m)
            except CalibrationError as e:
                rejected.append(f"cloud at {cloud.stamp_ns} ns: {e}")
                continue
            observations.append((cloud.stamp_ns, p_cam))
            segments[cloud.stamp_ns] = segment
        else:
            obs = rosmsg.decode_blob(m.data)
            observations.append((obs.stamp_ns, np.array(obs.position)))
    p, T, stamps = [], [], []
    for stamp_ns, p_cam in observations:
        try:
            T.append(poses.pair(stamp_ns, opts))
        except NotPaired as e:
            rejected.append(str(e))
            continue
        p.append(p_cam)
        stamps.append(stamp_ns)
    if not p:
        raise InputMismatch(
            f"{path}: no usable samples ({len(observations)} observations on "
            f"{topics[1]!r}, {len(poses)} flange poses on {pose_topic!r}); {rejected[:3]}"
        )
    for r in rejected:
        log.info("skipped: %s", r)
    radius = None
    views = [segments.get(t) for t in stamps]
    if target == "ball" and radius_m is None and len(views) >= 2 and all(v is not None for v in views):
        from ..targets.sphere_shared import fit_shared

        spheres = fit_shared([v for v in views if v is not None])
        p, radius = [s.p_cam for s in spheres], spheres[0].radius_m
    return McapSamples(np.array(p), np.array(T), stamps, rejected, radius)
