"""A launched robot's description beside its shared memory, so tools on the same host can draw the arm.

`plem launch` writes `/dev/shm/plem_description_{robot_id}.json` (atomically, owner-only or readable by
the group of `shm_group:=`) before it starts the driver, and removes it when it stops: the URDF as
robot_description carries it, the directories of the packages its `package://` URIs name, and the tool
link. Both steps also remove what killed launches and recorders left (`remove_stale_files`). A reader
takes it only when it is a regular file of its own user or root, small, of the expected shape, and
written by a launch that still runs.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from plem.core.files import UntrustedFile, read_trusted, remove_own, write_shared
from plem.errors import PlemError
from plem.ipc.leftovers import remove_stale_files
from plem.ipc.segment import SHM_DIRECTORY
from plem.ipc.state_segment import process_alive

#: The largest description file read (a URDF of a few thousand lines fits many times).
MAX_DESCRIPTION_BYTES = 16 << 20


class DescriptionUnavailable(PlemError):
    """No launch on this host shares the description of the robot asked for."""


@dataclass(frozen=True)
class SharedDescription:
    """What a launch shares about its robot's description."""

    urdf: str
    packages: dict[str, str] = field(default_factory=dict)   # package name → directory, for package:// URIs
    pid: int = 0


def description_path(robot_id: str) -> Path:
    """The description file of `robot_id` in /dev/shm."""
    return SHM_DIRECTORY / f"plem_description_{robot_id}.json"


def share_description(robot_id: str, description: SharedDescription, group: int | None = None) -> None:
    """Replace the robot's description file (owner-only, or 0640 with `group`); remove stale ones first."""
    remove_stale_files()
    write_shared(description_path(robot_id), json.dumps(asdict(description)), group)


def remove_description(robot_id: str) -> None:
    """Remove the description file if it is this user's, and the files killed launches and recorders left."""
    remove_own(description_path(robot_id))
    remove_stale_files()


def _unavailable(robot_id: str, why: str) -> DescriptionUnavailable:
    return DescriptionUnavailable(
        f"no description of robot '{robot_id}' on this host",
        what=f"a running `plem launch` of robot '{robot_id}' on this host, which shares its URDF in "
             f"{description_path(robot_id)}",
        why=why, how=f"start it with `plem launch robot_id:={robot_id} ...`, name another robot "
                     "(`plem view ROBOT_ID`), or view a robot on another host with `plem view --ros ROBOT_ID`")


def read_description(robot_id: str) -> SharedDescription:
    """The description a running launch shares; DescriptionUnavailable when there is none to trust."""
    path = description_path(robot_id)
    try:
        data = read_trusted(path, MAX_DESCRIPTION_BYTES)
    except FileNotFoundError:
        raise _unavailable(robot_id, f"{path} does not exist") from None
    except (UntrustedFile, OSError) as error:
        raise _unavailable(robot_id, f"{path} is not to be trusted: {error}") from None
    try:
        payload = json.loads(data or b"")
        description = SharedDescription(str(payload["urdf"]), {str(k): str(v) for k, v in payload["packages"].items()},
                                        int(payload["pid"]))
    except (ValueError, KeyError, TypeError, AttributeError) as error:
        raise _unavailable(robot_id, f"{path} is not a description plem wrote ({type(error).__name__})") from None
    if not process_alive(description.pid):
        raise _unavailable(robot_id, f"the launch that wrote {path} (pid {description.pid}) has ended")
    return description
