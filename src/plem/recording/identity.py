"""Who recorded a segment: the robot, its serial and model, the host and plem's version, in every bag's metadata.

The recorder puts these in each segment's metadata.yaml (`custom_data`, keys `plem.*`), so a segment alone
says whose it is; the fleet export copies them into the dataset's `segments` table. Bags of an older plem,
and segments rebuilt by `plem bag repair`, lack them: readers take them as unknown.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Iterable

import plem

IDENTITY_PREFIX = "plem."


def identity(robot_id: str, serial: str | None, model: str | None, joint_names: Iterable[str]) -> dict[str, str]:
    """The custom_data of one robot's segments (values are strings, as rosbag2 requires; '' for unknown)."""
    return {f"{IDENTITY_PREFIX}{key}": value for key, value in (
        ("robot_id", robot_id), ("serial", serial or ""), ("model", model or ""), ("host", socket.gethostname()),
        ("plem_version", plem.__version__), ("joint_names", json.dumps(list(joint_names))))}
