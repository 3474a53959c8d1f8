"""SofIA shared runtime, what every process runs on: the Zenoh session helper, the service status
endpoint and worker plumbing, the query client, payload limits, command output, the bus tools
(``sofia echo/query/health``), the ROS 2 bridge and the root ``sofia`` command.

The messages and key expressions that travel on the bus are in :mod:`sofia_schemas`.
"""

from .client import QueryError, ask, query
from .service import StatusEndpoint, StopFlag, serve
from .zenoh_config import ZenohOptions, add_zenoh_args, open_session, zenoh_config

__all__ = [
    "QueryError", "StatusEndpoint", "StopFlag", "ZenohOptions", "add_zenoh_args", "ask",
    "open_session", "query", "serve", "zenoh_config",
]  # fmt: skip
