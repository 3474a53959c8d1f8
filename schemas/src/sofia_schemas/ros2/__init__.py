"""SofIA on the ROS 2 graph: the rmw_zenoh protocol, ROS 2 types shipped with the project, the
conversions between SofIA's messages and standard ROS 2 messages, and the bridge service.

Needs the ``ros`` extra (rosbags for CDR, scipy for transforms).
"""

from .rmw import Attachment, Graph, Node, Qos, data_key
from .typesupport import UnknownRosTypeError, dds_type_name, shipped_types, type_hash

__all__ = [
    "Attachment", "Graph", "Node", "Qos", "UnknownRosTypeError", "data_key", "dds_type_name",
    "shipped_types", "type_hash",
]  # fmt: skip
