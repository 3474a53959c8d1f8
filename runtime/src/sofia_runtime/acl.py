"""Who may do what on the secure bus: one table (:data:`RIGHTS`), rendered into the
``access_control`` block of ``docker/zenoh/router-secure.json5`` by :func:`access_control`.

Zenoh's access control matches a request's key expression against a rule's only when the request
is *included in* the rule's (``a/*`` is not included in ``a/b``). So with ``default_permission:
"deny"`` and allow rules on exact keys only, every wildcard request (``sofia/R/gripper/*``,
``sofia/**``, ``sofia/R/**/result``, ``sofia/R/gripper/com$*``) matches no allow rule and is
denied, and deny rules are not needed. The robot chunk of each rule is ``*``: an identity's exact
rights hold for every robot id on that router.

Rights: ``pub`` (put/delete in; subscriber declarations out, so the publisher routes to them),
``sub`` (subscriber declarations in; puts out), ``query`` (queries in; replies and queryable
declarations out), ``answer`` (queryable declarations and replies in; queries out).

    python -m sofia_runtime.acl   # prints the block to paste into router-secure.json5
"""

from __future__ import annotations

import json
from typing import Any

STATUS = ("calibrator", "detector", "gripper", "arm", "camera", "replay", "viz", "ros2")
CAL_OPS = ("add", "remove", "reset", "solve", "save", "samples")
DATA = ("points", "camera/points", "camera/camera_info", "flange/pose", "detector/detections",
        "calibrator/blob", "calibrator/result", "gripper/state", "arm/state", "arm/joint_states",
        "arm/progress", "pick/target")  # fmt: skip
READ_STATUS = tuple(f"{s}/status" for s in STATUS)


def _own_status(service: str) -> dict[str, tuple[str, ...]]:
    return {"pub": (f"{service}/status",), "answer": (f"{service}/status",)}


def _merge(*parts: dict[str, tuple[str, ...]]) -> dict[str, tuple[str, ...]]:
    out: dict[str, tuple[str, ...]] = {}
    for part in parts:
        for right, keys in part.items():
            out[right] = tuple(dict.fromkeys(out.get(right, ()) + keys))
    return out


# identity -> right -> keys below sofia/<robot>/
RIGHTS: dict[str, dict[str, tuple[str, ...]]] = {
    "calibrator": _merge(
        _own_status("calibrator"),
        {
            "pub": ("calibrator/result",),
            "sub": ("flange/pose", "calibrator/blob", "camera/points"),
            "answer": ("calibrator/result", *(f"calibrator/{op}" for op in CAL_OPS)),
        },
    ),
    "detector": _merge(
        _own_status("detector"),
        {
            "pub": ("detector/detections", "pick/target"),
            "sub": ("points", "camera/points", "flange/pose", "calibrator/result"),
            "query": ("calibrator/result",),
            "answer": ("detector/detect",),
        },
    ),
    "gripper": _merge(_own_status("gripper"), {"pub": ("gripper/state",), "answer": ("gripper/command",)}),
    "camera": _merge(
        _own_status("camera"),
        {
            "pub": ("camera/points", "camera/camera_info"),
            "sub": ("flange/pose", "calibrator/result"),
            "query": ("calibrator/result",),
        },
    ),
    "replay": _merge(
        _own_status("replay"),
        {
            "pub": ("points", "camera/points", "camera/camera_info", "flange/pose", "calibrator/blob"),
        },
    ),
    "arm": _merge(
        _own_status("arm"),
        {
            "pub": ("arm/state", "arm/joint_states", "arm/progress", "flange/pose"),
            "sub": ("pick/target", "camera/points", "calibrator/result", "gripper/state"),
            "query": (
                "gripper/command",
                "detector/detect",
                "calibrator/result",
                *(f"calibrator/{op}" for op in CAL_OPS),
                *READ_STATUS,
            ),
            "answer": ("arm/command",),
        },
    ),
    "operator": {  # a person at the CLI; ROS 2 nodes of other machines join as operator too
        "sub": DATA + READ_STATUS,
        "query": (
            "gripper/command",
            "arm/command",
            "detector/detect",
            "calibrator/result",
            *(f"calibrator/{op}" for op in CAL_OPS),
            *READ_STATUS,
        ),
    },
    "sofia": {  # tools: sofia echo / query / health, read only
        "sub": DATA + READ_STATUS,
        "query": ("detector/detect", "calibrator/result", "calibrator/samples", *READ_STATUS),
    },
    "viz": _merge(
        _own_status("viz"), {"sub": DATA + READ_STATUS, "query": ("calibrator/result", *READ_STATUS)}
    ),
    "ros2": _merge(
        _own_status("ros2"),
        {
            "pub": ("camera/points", "flange/pose"),
            "sub": (
                "points",
                "camera/points",
                "detector/detections",
                "flange/pose",
                "gripper/state",
                "pick/target",
            ),
            "query": ("detector/detect", "calibrator/result"),
        },
    ),
}
ROS2_GRAPH = ("ros2", "operator")  # rmw_zenoh keys of ROS domain 0 and its graph tokens
ROS2_KEYS = ("0/**", "@ros2_lv/0/**")
ALL = ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
       "liveliness_token", "liveliness_query", "declare_liveliness_subscriber"]  # fmt: skip
FLOWS = {  # right -> ((messages, flow), ...)
    "pub": ((["put", "delete"], "ingress"), (["declare_subscriber"], "egress")),
    "sub": ((["declare_subscriber"], "ingress"), (["put", "delete"], "egress")),
    "query": ((["query"], "ingress"), (["reply", "declare_queryable"], "egress")),
    "answer": ((["declare_queryable", "reply"], "ingress"), (["query"], "egress")),
}


def access_control(robot: str = "*") -> dict[str, Any]:
    """The router's ``access_control`` block: one rule per identity, right and flow."""
    rules, policies = [], []
    for user, rights in RIGHTS.items():
        ids = []
        for right, keys in rights.items():
            for messages, flow in FLOWS[right]:
                rule_id = f"{user}-{right}-{flow}"
                rules.append({"id": rule_id, "messages": messages, "flows": [flow], "permission": "allow",
                              "key_exprs": [f"sofia/{robot}/{k}" for k in keys]})  # fmt: skip
                ids.append(rule_id)
        policies.append({"id": user, "rules": ids, "subjects": [user]})
    rules.append({"id": "ros2-graph", "messages": ALL, "flows": ["ingress", "egress"], "permission": "allow",
                  "key_exprs": list(ROS2_KEYS)})  # fmt: skip
    policies += [{"id": f"ros2-graph-{u}", "rules": ["ros2-graph"], "subjects": [u]} for u in ROS2_GRAPH]
    subjects = [{"id": u, "usernames": [u]} for u in RIGHTS]
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}  # fmt: skip


if __name__ == "__main__":
    print(json.dumps(access_control(), indent=2))
