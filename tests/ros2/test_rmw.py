"""The rmw_zenoh protocol pieces: type hashes, attachments, QoS strings, keys, the tf chain."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_runtime.ros2.rmw import STATIC_QOS, Attachment, Qos, data_key, mangle
from sofia_runtime.ros2.tfchain import TfChain
from sofia_schemas.errors import PayloadError
from sofia_schemas.ros2 import convert as cv
from sofia_schemas.ros2.typesupport import MSGS_DIR, definition, shipped_types, type_hash
from zenoh_ros2_sdk.qos import QosDurability, QosProfile, QosReliability
from zenoh_ros2_sdk.utils import compute_service_type_hash, get_type_hash

# published by ROS 2 Jazzy (rmw_zenoh liveliness tokens seen on real systems)
KNOWN = {
    "sensor_msgs/msg/PointCloud2": "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5",
    "tf2_msgs/msg/TFMessage": "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
}
PREFIXES = {
    "geometry_msgs/msg/PoseStamped": "RIHS01_10f3786d7d40fd2b",
    "sensor_msgs/msg/JointState": "RIHS01_a13ee3",
}


def test_type_hashes_match_ros2() -> None:
    for name, value in KNOWN.items():
        assert type_hash(name) == value
    for name, prefix in PREFIXES.items():
        assert type_hash(name).startswith(prefix)


def _dependencies(typename: str, seen: dict[str, str]) -> dict[str, str]:
    from sofia_schemas.ros2.typesupport import fields

    for f in fields(typename):
        nested = f["type"]["nested_type_name"]
        if nested and nested not in seen:
            seen[nested] = definition(nested)
            _dependencies(nested, seen)
    return seen


# ServiceEventInfo has a `char[16]` field: rosidl maps .msg `char` to uint8 (as the SDK's own service
# hash does), the SDK's .msg parser to FIELD_TYPE_CHAR; it is checked through every service's hash.
@pytest.mark.parametrize("typename", [t for t in shipped_types() if t != "service_msgs/msg/ServiceEventInfo"])
def test_type_hash_agrees_with_an_independent_implementation(typename: str) -> None:
    if "/srv/" in typename:
        parts = {p: definition(f"{typename}_{p}") for p in ("Request", "Response")}
        deps: dict[str, str] = {}
        for p in parts:
            _dependencies(f"{typename}_{p}", deps)
        other = compute_service_type_hash(typename, parts["Request"], parts["Response"], deps)
    else:
        other = get_type_hash(typename, definition(typename), _dependencies(typename, {}))
    assert type_hash(typename) == other
    assert (MSGS_DIR / typename.split("/")[0]).is_dir()


def test_attachment_wire_format() -> None:
    gid = bytes(range(16))
    att = Attachment(7, 1_700_000_000_000_000_001, gid)
    raw = att.encode()
    assert raw == struct.pack("<qqB", 7, 1_700_000_000_000_000_001, 16) + gid
    assert Attachment.decode(raw) == att
    keyed = (b"\x0fsequence_number" + struct.pack("<q", 7) + b"\x10source_timestamp"
             + struct.pack("<q", 1_700_000_000_000_000_001) + b"\x0asource_gid\x10" + gid)  # fmt: skip
    assert Attachment.decode(keyed) == Attachment(
        7, 1_700_000_000_000_000_001, gid, keyed=True
    )  # before 0.2.4
    assert Attachment.decode(keyed).encode() == keyed  # a reply to such a client is in its form
    with pytest.raises(PayloadError, match="33"):
        Attachment.decode(raw[:-1])


def test_qos_strings_and_keys_match_the_sdk() -> None:
    assert Qos().encode() == QosProfile().encode() == "::,10:,:,:,,"
    sdk_static = QosProfile(durability=QosDurability.TRANSIENT_LOCAL, history_depth=1)
    assert STATIC_QOS.encode() == sdk_static.encode()
    assert (
        Qos(reliable=False, depth=5).encode()
        == QosProfile(reliability=QosReliability.BEST_EFFORT, history_depth=5).encode()
    )
    assert data_key(0, "/sofia/panda/points", cv.POINTCLOUD2) == (
        "0/sofia/panda/points/sensor_msgs::msg::dds_::PointCloud2_/" + KNOWN[cv.POINTCLOUD2]
    )
    assert mangle("/sofia/panda/points") == "%sofia%panda%points"


def test_tf_chain_composes_the_flange_pose() -> None:
    rng = np.random.default_rng(1)
    Ts = []
    for _ in range(3):
        T = np.eye(4)
        T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        T[:3, 3] = rng.normal(size=3)
        Ts.append(T)
    frames = ["panda_link0", "panda_link3", "panda_link6", "panda_link8"]
    msgs = [
        cv.transform_stamped(
            5 + i, frames[i], frames[i + 1], T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_quat()
        )
        for i, T in enumerate(Ts)
    ]
    chain = TfChain("panda_link0", "panda_link8")
    assert chain.update(msgs[:2]) is None  # incomplete
    pose = chain.update(
        [*msgs[2:], cv.transform_stamped(9, "panda_link8", "panda_hand", (0, 0, 0.1), (0, 0, 0, 1))]
    )
    assert pose is not None and pose.stamp_ns == 7
    assert np.allclose(pose.matrix(), Ts[0] @ Ts[1] @ Ts[2], atol=1e-9)
    assert chain.update([msgs[0]]) is not None and chain.update([]) is None  # touched / untouched
