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
from typing import Any

from plem.core.config.yaml_document import YamlDocument, YamlSyntaxError, read_yaml
from plem.errors import ConfigError, raise_collected
from plem.launch.arguments import NAMES

HOW = "write robots: as a list of mappings, each with its own robot_id (see `plem launch --help`)"
ALLOWED = frozenset(NAMES) - {"robots"}


def _text(value: object) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def _read(path: Path) -> YamlDocument:
    """The parsed file; unreadable, malformed or oversized files are a ConfigError naming the robots file."""
    try:
        return read_yaml(path, "robots file")
    except ConfigError as error:
        summary = (f"the robots file {path} is not valid YAML" if isinstance(error, YamlSyntaxError)
                   else f"cannot read the robots file {path}")
        raise ConfigError(summary, what=error.what, why=error.why,
                          how=f"{error.how} (the file named by robots:=)") from None


def _entries(document: YamlDocument) -> list[Any]:
    """The non-empty list under `robots:`; anything else is a ConfigError saying what was found and where."""
    path, data = document.path, document.root
    entries = data.get("robots") if isinstance(data, dict) else None
    if isinstance(entries, list) and entries:
        return entries
    if data is None:
        found = f"{path}: the file is empty"
    elif not isinstance(data, dict):
        found = f"{path}: the file holds {_kind(data)}"
    elif "robots" not in data:
        found = f"{path}: no robots: key (keys: {', '.join(map(str, data))})"
    else:
        found = f"{path}:{document.line('robots')}: robots: is {_kind(entries)}"
    raise ConfigError(f"{path} lists no robots", what="a top-level robots: list of mappings", why=found, how=HOW)


def _kind(value: object) -> str:
    """'a list', 'a mapping', 'empty', 'the single value 5' ... as a message names a YAML value."""
    if value is None or value == []:
        return "empty"
    if isinstance(value, list):
        return "a list"
    return "a mapping" if isinstance(value, dict) else f"the single value {value!r}"


def _entry_problems(document: YamlDocument, index: int, entry: Any) -> list[ConfigError]:
    """What is wrong with robot `index`: not a mapping, unknown keys, values that are not single values, no robot_id."""
    path = document.path
    if not isinstance(entry, dict):
        return [ConfigError(f"robot {index} in {path} is not a mapping", what="each robot as a mapping of launch "
                            "arguments, e.g. {robot_id: arm_left, bus: mock}",
                            why=f"{path}:{document.line('robots', index)}: robot {index} is {_kind(entry)}", how=HOW)]
    problems: list[ConfigError] = []
    unknown = sorted(str(key) for key in entry if str(key) not in ALLOWED)
    if unknown:
        problems.append(ConfigError(
            f"robot {index} in {path} has unknown keys", what=f"launch arguments: {', '.join(sorted(ALLOWED))}",
            why=f"{path}:{document.line('robots', index, unknown[0])}: unknown: {', '.join(unknown)}",
            how="spell the keys as the launch arguments"))
    for key, value in entry.items():
        if value is None or isinstance(value, (list, dict)):
            problems.append(ConfigError(
                f"robot {index} in {path}: {key} is not a single value",
                what=f"{key} as one value (text, a number or true/false), as {key}:=VALUE takes it",
                why=f"{path}:{document.line('robots', index, key)}: {key} is {_kind(value)}",
                how=f"write a single value after '{key}:'"))
    if "robot_id" not in entry or entry["robot_id"] == "":
        problems.append(ConfigError(
            f"robot {index} in {path} has no robot_id", what="a robot_id per robot",
            why=f"{path}:{document.line('robots', index)}: shared memory and topics of robots must not collide",
            how="add robot_id: <name>"))
    return problems


def load_robots(path: str | Path, common: Mapping[str, str]) -> list[dict[str, str]]:
    """Each robot's launch arguments: the command line's, overridden by its entry in the file."""
    document = _read(Path(path).expanduser())
    path = document.path
    entries = _entries(document)
    problems = [problem for index, entry in enumerate(entries) for problem in _entry_problems(document, index, entry)]
    seen: dict[str, int] = {}
    for index, entry in enumerate(entries):
        robot_id = entry.get("robot_id") if isinstance(entry, dict) else None
        if robot_id is None or isinstance(robot_id, (list, dict)):
            continue
        robot_id = _text(robot_id)
        if robot_id in seen:
            problems.append(ConfigError(
                f"robot_id {robot_id} appears twice in {path}", what="a distinct robot_id per robot",
                why=f"{path}:{document.line('robots', index, 'robot_id')}: robots {seen[robot_id]} and {index} "
                    f"are both {robot_id}",
                how="give each robot its own robot_id"))
        seen.setdefault(robot_id, index)
    raise_collected(problems, str(path))
    return [{**{k: v for k, v in common.items() if k != "robots"}, **{str(k): _text(v) for k, v in entry.items()}}
            for entry in entries]
