"""SofIA on the ROS 2 graph: the rmw_zenoh protocol (liveliness tokens, attachments, QoS), the
bridge between SofIA's keys and ROS 2 topics, services and /tf, and its service (``sofia ros2``).

Needs the ``ros`` extra (rosbags for CDR, scipy for transforms).
"""

from .rmw import Attachment, Graph, Node, Qos, data_key

__all__ = ["Attachment", "Graph", "Node", "Qos", "data_key"]
