"""SofIA live view in Foxglove: ``sofia viz serve`` (a Foxglove WebSocket server fed from the bus)."""

from .errors import PortInUse, VizError
from .scene import board_entity, calibration_entity, detection_entities, pick_entity

__all__ = ["PortInUse", "VizError", "board_entity", "calibration_entity", "detection_entities", "pick_entity"]
