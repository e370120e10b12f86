"""A parsed YAML file that remembers where every key came from, for errors with file:line."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.error import MarkedYAMLError, YAMLError

from plem.errors import ConfigError


def to_plain(node: Any) -> Any:
    """Convert ruamel's round-trip containers and scalars into plain dict/list/int/float/str/bool."""
    if isinstance(node, dict):
        return {str(k) if not isinstance(k, (int, float, bool)) else k: to_plain(v) for k, v in node.items()}
    if isinstance(node, list):
        return [to_plain(v) for v in node]
    if isinstance(node, bool) or node is None:
        return node
    for plain in (int, float, str):
        if isinstance(node, plain):
            return plain(node)
    return node


def split_key(key: str) -> list[str]:
    """`robot.control.timeout` → ['robot', 'control', 'timeout']; an empty key means the whole document."""
    return [part for part in key.split(".")] if key else []


@dataclass(frozen=True)
class YamlDocument:
    """The round-trip tree of one YAML file plus its path, so lookups can say file:line."""

    path: Path
    root: Any

    def lookup(self, key: str) -> tuple[Any, int | None]:
        """The node at dotted `key` and its 1-based line; raises ConfigError naming the missing part."""
        node = self.root
        line: int | None = 1
        walked: list[str] = []
        for part in split_key(key):
            container_line = line
            if isinstance(node, dict) and part in node:
                line = node.lc.key(part)[0] + 1 if hasattr(node, "lc") else line
                node = node[part]
            elif isinstance(node, list) and part.lstrip("-").isdigit() and -len(node) <= int(part) < len(node):
                index = int(part)
                line = node.lc.item(index % len(node))[0] + 1 if hasattr(node, "lc") else line
                node = node[index]
            else:
                raise self._missing(key, walked, part, node, container_line)
            walked.append(part)
        return node, line

    def _missing(self, key: str, walked: list[str], part: str, node: Any, line: int | None) -> ConfigError:
        where = ".".join(walked) or "the top level"
        if isinstance(node, dict):
            keys = ", ".join(str(k) for k in node) or "none"
            found = f"no key '{part}' under {where} ({self.path}:{line}); keys there: {keys}"
        elif isinstance(node, list):
            found = f"{where} is a list of {len(node)} items ({self.path}:{line}); '{part}' is not a valid index"
        else:
            found = f"{where} is a single value ({type(node).__name__}) at {self.path}:{line}, not a mapping"
        return ConfigError(
            f"Key '{key}' not found in {self.path.name}",
            what=f"a value at key path '{key}' in {self.path}",
            why=found,
            how=f"add '{key}' to {self.path}, or fix the key path (dots separate nested keys)",
        )


def read_yaml(path: Path) -> YamlDocument:
    """Parse `path`; YAML syntax problems become a ConfigError with the line and column."""
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
    try:
        root = YAML(typ="rt", pure=True).load(text)
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        problem = " ".join(filter(None, [exc.context, exc.problem])) or "invalid YAML"
        raise ConfigError(
            f"YAML syntax error in {path.name}",
            what=f"valid YAML in {path}",
            why=f"{where}: {problem}",
            how="fix the YAML at that line (check indentation, colons and quoting)",
        ) from None
    except YAMLError as exc:
        raise ConfigError(
            f"YAML syntax error in {path.name}",
            what=f"valid YAML in {path}",
            why=str(exc),
            how="fix the YAML syntax",
        ) from None
    return YamlDocument(path=path, root=root)
