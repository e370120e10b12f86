"""A parsed YAML file that remembers the line of every key and item, for errors with file:line.

Parsing uses libyaml's composer (C) and builds plain Python values plus a line index in one walk; it
is an order of magnitude faster than a pure-Python round-trip parser, which matters because every
launch and `plem validate` reads several of these files. Duplicate keys are an error, not "last wins".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from plem.errors import ConfigError

_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_constructor = yaml.constructor.SafeConstructor()
KeyPath = tuple[str, ...]


def split_key(key: str) -> list[str]:
    """`robot.control.timeout` → ['robot', 'control', 'timeout']; an empty key means the whole document."""
    return key.split(".") if key else []


class _DuplicateKey(Exception):
    def __init__(self, key: str, line: int, first: int) -> None:
        super().__init__(key)
        self.key, self.line, self.first = key, line, first


def _build(node: yaml.Node, path: KeyPath, lines: dict[KeyPath, int]) -> Any:
    """Plain value of `node`, recording the 1-based line of every key and list item under `path`."""
    if isinstance(node, yaml.MappingNode):
        _constructor.flatten_mapping(node)
        result: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            key = _constructor.construct_object(key_node, deep=True)
            key = key if isinstance(key, (str, int, float, bool)) or key is None else str(key)
            child = (*path, str(key))
            if key in result:
                raise _DuplicateKey(str(key), key_node.start_mark.line + 1, lines[child])
            lines[child] = key_node.start_mark.line + 1
            result[key] = _build(value_node, child, lines)
        return result
    if isinstance(node, yaml.SequenceNode):
        items = []
        for index, item in enumerate(node.value):
            child = (*path, str(index))
            lines[child] = item.start_mark.line + 1
            items.append(_build(item, child, lines))
        return items
    return _constructor.construct_object(node, deep=True)


@dataclass(frozen=True)
class YamlDocument:
    """Plain values of one YAML file, its path, and the line of each key path."""

    path: Path
    root: Any
    lines: dict[KeyPath, int] = field(default_factory=dict)

    def line(self, *parts: str | int) -> int:
        """1-based line of the key or item at `parts` (1 for the document itself or an unknown path)."""
        return self.lines.get(tuple(str(p) for p in parts), 1)

    def lookup(self, key: str) -> tuple[Any, int]:
        """The value at dotted `key` and its line; raises ConfigError naming the missing part."""
        node: Any = self.root
        walked: list[str] = []
        for part in split_key(key):
            if isinstance(node, dict) and part in node:
                node = node[part]
            elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
                node = node[int(part)]
            else:
                raise self._missing(key, walked, part, node)
            walked.append(part)
        return node, self.line(*walked)

    def _missing(self, key: str, walked: list[str], part: str, node: Any) -> ConfigError:
        where = ".".join(walked) or "the top level"
        at = f"{self.path}:{self.line(*walked)}"
        if isinstance(node, dict):
            keys = ", ".join(str(k) for k in node) or "none"
            found = f"no key '{part}' under {where} ({at}); keys there: {keys}"
        elif isinstance(node, list):
            found = f"{where} is a list of {len(node)} items ({at}); '{part}' is not a valid index"
        else:
            found = f"{where} is a single value ({type(node).__name__}) at {at}, not a mapping"
        return ConfigError(
            f"Key '{key}' not found in {self.path.name}",
            what=f"a value at key path '{key}' in {self.path}",
            why=found,
            how=f"add '{key}' to {self.path}, or fix the key path (dots separate nested keys)",
        )


class YamlSyntaxError(ConfigError):
    """A YAML file that does not parse; `line` is 1-based when known."""

    line: int | None = None


def _syntax_error(path: Path, where: str, problem: str, line: int | None = None) -> YamlSyntaxError:
    error = YamlSyntaxError(
        f"YAML syntax error in {path.name}",
        what=f"valid YAML in {path}",
        why=f"{where}: {problem}",
        how="fix the YAML at that line (check indentation, colons, quoting and repeated keys)",
    )
    error.line = line
    return error


def read_yaml(path: Path) -> YamlDocument:
    """Parse `path`; syntax problems and duplicate keys become a ConfigError with the line."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(
            f"File not found: {path}",
            what=f"a readable YAML file at {path}",
            why="the file does not exist",
            how="check the path, or create the file",
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(
            f"Cannot read {path}",
            what=f"a readable UTF-8 YAML file at {path}",
            why=str(exc),
            how="check the file's permissions and encoding",
        ) from None
    lines: dict[KeyPath, int] = {}
    try:
        node = yaml.compose(text, Loader=_Loader)
        root = _build(node, (), lines) if node is not None else None
    except _DuplicateKey as dup:
        raise _syntax_error(path, f"{path}:{dup.line}", f"key '{dup.key}' repeats the one on line {dup.first}",
                            dup.line) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        raise _syntax_error(path, where, " ".join(filter(None, [exc.context, exc.problem])) or "invalid YAML",
                            mark.line + 1 if mark else None) from None
    except RecursionError:
        raise _syntax_error(path, str(path),
                            "an alias refers to itself (recursive anchor), or nesting is too deep") from None
    except (yaml.YAMLError, ValueError, TypeError) as exc:
        raise _syntax_error(path, str(path), " ".join(str(exc).split()) or type(exc).__name__) from None
    return YamlDocument(path=path, root=root, lines=lines)
