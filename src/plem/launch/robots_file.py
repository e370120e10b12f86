"""`robots:=FILE.yaml`: several robots in one launch, each with its own robot_id, bus and interface.

```yaml
robots:
  - {robot_id: arm_left,  bus: mock, robot_type: indy7_v2}
  - {robot_id: arm_right, bus: ethercat, eth_interface: enp3s0, master_index: 1}
```
Arguments given on the command line apply to every robot unless the robot's entry sets them.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import yaml

from plem.errors import ConfigError
from plem.launch.arguments import NAMES


def _text(value: object) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def load_robots(path: str | Path, common: Mapping[str, str]) -> list[dict[str, str]]:
    """Each robot's launch arguments: the command line's, overridden by its entry in the file."""
    path = Path(path).expanduser()
    how = "write robots: as a list of mappings, each with its own robot_id (see `plem launch --help`)"
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as error:
        raise ConfigError(f"cannot read the robots file {path}", what="a readable YAML file",
                          why=error.strerror or str(error), how="check the robots:= path") from None
    except yaml.YAMLError as error:
        raise ConfigError(f"the robots file {path} is not valid YAML", what="YAML", why=str(error).splitlines()[0],
                          how=how) from None
    entries = data.get("robots") if isinstance(data, dict) else None
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise ConfigError(f"{path} lists no robots", what="a top-level robots: list of mappings",
                          why=f"found {type(entries).__name__ if entries is not None else 'no robots: key'}", how=how)
    robots: list[dict[str, str]] = []
    seen: dict[str, int] = {}
    allowed = set(NAMES) - {"robots"}
    for index, entry in enumerate(entries):
        unknown = sorted(set(map(str, entry)) - allowed)
        if unknown:
            raise ConfigError(f"robot {index} in {path} has unknown keys", what=f"launch arguments: "
                              f"{', '.join(sorted(allowed))}", why=f"unknown: {', '.join(unknown)}",
                              how="spell the keys as the launch arguments")
        robot_id = entry.get("robot_id")
        if not robot_id:
            raise ConfigError(f"robot {index} in {path} has no robot_id", what="a robot_id per robot",
                              why="shared memory and topics of robots must not collide", how="add robot_id: <name>")
        if robot_id in seen:
            raise ConfigError(f"robot_id {robot_id} appears twice in {path}", what="a distinct robot_id per robot",
                              why=f"robots {seen[robot_id]} and {index} are both {robot_id}",
                              how="give each robot its own robot_id")
        seen[robot_id] = index
        robots.append({**{k: v for k, v in common.items() if k != "robots"},
                       **{str(k): _text(v) for k, v in entry.items()}})
    return robots
