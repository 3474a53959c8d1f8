"""SofIA as a whole on one machine: the launcher behind ``sofia up`` (router and services as local
processes, restarted when they die, health from their status) and the end-to-end demo behind
``sofia demo``."""

from .demo import run_demo
from .launcher import Launcher, ServiceSpec

__all__ = ["Launcher", "ServiceSpec", "run_demo"]
