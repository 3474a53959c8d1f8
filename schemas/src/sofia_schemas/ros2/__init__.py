"""ROS 2 on the wire: the ROS 2 types shipped with the project (CDR through rosbags, RIHS01 type
hashes) and the conversions between SofIA's messages and standard ROS 2 messages. The rmw_zenoh
protocol and the bridge service are in :mod:`sofia_runtime.ros2`.

Needs the ``ros`` extra (rosbags for CDR, scipy for transforms).
"""

from .typesupport import UnknownRosTypeError, dds_type_name, shipped_types, type_hash

__all__ = ["UnknownRosTypeError", "dds_type_name", "shipped_types", "type_hash"]
