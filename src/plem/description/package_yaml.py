"""The YAML files of a description package (joint_limits, kinematics, controllers), read as ROS 2 reads them.

Two shapes real packages use are accepted:

- xacro's unit tags (`!degrees 180`, `!radians pi/2`, `!millimeters 5`, ...), which `xacro.load_yaml` turns
  into radians and metres: the value (a number, or arithmetic of numbers and `pi`, `e`, `tau`) times the
  unit's factor;
- a ROS 2 parameters file: node names (`/**`, `move_group`, `/**/controller_manager`, namespaces nested or in
  the name) each holding `ros__parameters:`. Each file is brought to the plain form the protocol shows, with
  the line of every key kept: joint_limits.yaml to `joint_limits:`, kinematics.yaml to its groups (MoveIt's
  `robot_description_kinematics` parameter), controllers.yaml to `node: ros__parameters:` per node. Parameters
  of a wildcard node (`/**`) apply to every node; a node's own parameters win over them, as in rclcpp.
"""

from __future__ import annotations

import ast
import math
import os
from collections.abc import Callable, Iterator
from fnmatch import fnmatchcase
from functools import lru_cache
from pathlib import Path
from typing import Any

from plem.core.config.yaml_document import KeyPath, ScalarTags, YamlDocument, read_yaml

PARAMETERS = "ros__parameters"
#: xacro's unit tags and their factors to radians or metres (xacro.ConstructUnits).
UNITS = {"!radians": 1.0, "!degrees": math.pi / 180.0, "!meters": 1.0, "!millimeters": 0.001, "!foot": 0.3048,
         "!inches": 0.0254}
_CONSTANTS = {"pi": math.pi, "e": math.e, "tau": math.tau}
_OPERATORS: dict[type[ast.AST], Callable[..., float]] = {
    ast.Add: float.__add__, ast.Sub: float.__sub__, ast.Mult: float.__mul__, ast.Div: float.__truediv__,
    ast.Pow: float.__pow__, ast.USub: float.__neg__, ast.UAdd: float.__pos__}
#: MoveIt's parameter holding kinematics.yaml's groups.
KINEMATICS_PARAMETER = "robot_description_kinematics"
CONTROLLER_MANAGER = "controller_manager"


def _evaluate(node: ast.AST) -> float:
    """The value of an arithmetic expression of numbers and pi, e, tau (what unit tags hold); ValueError else."""
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float) and not isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.Name) and node.id in _CONSTANTS:
        return _CONSTANTS[node.id]
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "math" \
            and node.attr in _CONSTANTS:
        return _CONSTANTS[node.attr]
    if isinstance(node, ast.UnaryOp) and type(node.op) in _OPERATORS:
        return _OPERATORS[type(node.op)](_evaluate(node.operand))
    if isinstance(node, ast.BinOp) and type(node.op) in _OPERATORS:
        try:
            return _OPERATORS[type(node.op)](_evaluate(node.left), _evaluate(node.right))
        except (ArithmeticError, ValueError) as error:
            raise ValueError(f"the arithmetic fails ({error})") from None
    raise ValueError("not a number or arithmetic of numbers and pi, e, tau")


def _unit(factor: float) -> Callable[[str], float]:
    def construct(text: str) -> float:
        try:
            expression = ast.parse(text.strip(), mode="eval").body
        except SyntaxError:
            raise ValueError("not a number or arithmetic of numbers and pi, e, tau") from None
        value = _evaluate(expression) * factor
        if not math.isfinite(value):
            raise ValueError("the value is not finite")
        return value
    return construct


UNIT_TAGS: ScalarTags = {tag: _unit(factor) for tag, factor in UNITS.items()}


class _Builder:
    """A plain document assembled from parts of a parameters file, each part keeping its lines."""

    def __init__(self, source: YamlDocument) -> None:
        self.source = source
        self.root: dict[Any, Any] = {}
        self.lines: dict[KeyPath, int] = {}

    def merge(self, target: KeyPath, value: Any, origin: KeyPath) -> None:
        """Put a copy of `value` (found at `origin` in the source) at `target`; mappings merge key by key, the
        later value of a key winning."""
        *parents, last = target
        node = self.root
        for key in parents:
            node = node[key]
        if isinstance(value, dict):
            if not isinstance(node.get(last), dict):
                node[last] = {}
                self.lines[target] = self.source.line(*origin)
            for key, item in value.items():
                self.merge((*target, str(key)), item, (*origin, str(key)))
            return
        node[last] = value
        self.lines[target] = self.source.line(*origin)
        if isinstance(value, list):
            for index in range(len(value)):
                self.lines[(*target, str(index))] = self.source.line(*origin, index)

    def document(self) -> YamlDocument:
        return YamlDocument(self.source.path, self.root, self.lines)


def _nodes(mapping: dict[Any, Any], at: KeyPath = ()) -> Iterator[tuple[KeyPath, dict[Any, Any]]]:
    """Each (key path, parameters) of a parameters file: a key path ends at a mapping holding ros__parameters."""
    for key, value in mapping.items():
        if not isinstance(value, dict):
            continue
        if PARAMETERS in value:
            if isinstance(value[PARAMETERS], dict):
                yield (*at, str(key)), value[PARAMETERS]
        else:
            yield from _nodes(value, (*at, str(key)))


def _node_name(path: KeyPath) -> str:
    """The node's own name (the last part of `/namespace/node`, however written); `*` for any node."""
    last = "/".join(path).rstrip("/").rsplit("/", 1)[-1]
    return "*" if last in ("*", "**", "") else last


def _in_rclcpp_order(nodes: list[tuple[KeyPath, dict[Any, Any]]]) -> list[tuple[KeyPath, dict[Any, Any]]]:
    """Wildcard nodes first, so that a node's own parameters override theirs."""
    return sorted(nodes, key=lambda node: "*" not in _node_name(node[0]))


def _unwrapped(document: YamlDocument, section: str | None) -> YamlDocument:
    """The plain form of a parameters file holding one mapping (`section` of the parameters, or all of them)."""
    builder = _Builder(document)
    for path, params in _in_rclcpp_order(list(_nodes(document.root))):
        origin = (*path, PARAMETERS)
        if section is None:  # kinematics.yaml: MoveIt's parameter, else the groups among the node's parameters
            if isinstance(params.get(KINEMATICS_PARAMETER), dict):
                wanted, origin = params[KINEMATICS_PARAMETER], (*origin, KINEMATICS_PARAMETER)
            else:
                wanted = {key: value for key, value in params.items() if isinstance(value, dict)}
            for key, value in wanted.items():
                builder.merge((str(key),), value, (*origin, str(key)))
        elif section in params:
            builder.merge((section,), params[section], (*origin, section))
    return builder.document()


def _by_node(document: YamlDocument) -> YamlDocument:
    """controllers.yaml as `node: ros__parameters:` per node, node names plain, wildcard parameters spread."""
    nodes = _in_rclcpp_order(list(_nodes(document.root)))
    names = [_node_name(path) for path, _ in nodes if _node_name(path) != "*"]
    names = list(dict.fromkeys([CONTROLLER_MANAGER, *names]))
    builder = _Builder(document)
    for path, params in nodes:
        pattern = _node_name(path)
        for name in names:
            if fnmatchcase(name, pattern):
                builder.merge((name,), {PARAMETERS: params}, path)
    return builder.document()


def _is_plain_controllers(root: dict[Any, Any]) -> bool:
    """Already `node: ros__parameters:` with plain node names at the top level."""
    return all(isinstance(body, dict) and PARAMETERS in body and "/" not in str(name) and "*" not in str(name)
               for name, body in root.items())


def _normalised(document: YamlDocument, kind: str) -> YamlDocument:
    root = document.root
    if not isinstance(root, dict) or not any(True for _ in _nodes(root)):
        return document
    if kind == "controllers.yaml":
        return document if _is_plain_controllers(root) else _by_node(document)
    if kind == "joint_limits.yaml" and "joint_limits" not in root:
        return _unwrapped(document, "joint_limits")
    if kind == "kinematics.yaml":
        return _unwrapped(document, None)
    return document


@lru_cache(maxsize=32)
def _read(path: Path, kind: str, signature: tuple[int, int, int]) -> YamlDocument:
    return _normalised(read_yaml(path, kind, UNIT_TAGS), kind)


def read_package_yaml(path: Path, kind: str | None = None) -> YamlDocument:
    """A package's YAML file (`kind`: its protocol name, e.g. "kinematics.yaml"; the file's name by default) in
    the plain form, xacro's unit tags resolved; re-read when the file changes. Raises ConfigError as `read_yaml`."""
    try:
        status = os.stat(path)
        signature = (status.st_mtime_ns, status.st_size, status.st_ino)
    except (OSError, ValueError):
        signature = (0, 0, 0)  # read_yaml reports it
    return _read(Path(path), kind or Path(path).name, signature)
