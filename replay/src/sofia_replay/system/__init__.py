"""The whole system on one machine: the end-to-end demo."""

from .demo import run_demo

__all__ = ["run_demo"]
