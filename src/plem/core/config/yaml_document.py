"""A parsed YAML file that remembers the line of every key and item, for errors with file:line.

Parsing uses libyaml's composer (C) and builds plain Python values plus a line index in one walk; it
is an order of magnitude faster than a pure-Python round-trip parser, which matters because every
launch and `plem validate` reads several of these files. Duplicate keys are an error, not "last wins".

Before composing, one pass over libyaml's events checks the file's shape: nesting depth, and the number of
values once every alias is expanded. Deep nesting would overflow the composer's C stack, and a few
nested aliases ("billion laughs") expand to billions of values; both are refused with the limit named.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from plem.core.files import read_regular_text
from plem.errors import ConfigError

_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_constructor = yaml.constructor.SafeConstructor()
KeyPath = tuple[str, ...]
#: Constructors of local scalar tags (`!degrees 90`) a reader accepts: the scalar's text in, its value out; a
#: ValueError's message becomes the error at the scalar's line.
ScalarTags = Mapping[str, Callable[[str], Any]]

#: Limits on a YAML file plem reads: no configuration, limits or controllers file comes near them.
MAX_YAML_BYTES = 4 * 1024 * 1024
MAX_YAML_DEPTH = 64
MAX_YAML_VALUES = 1_000_000


def split_key(key: str) -> list[str]:
    """`robot.control.timeout` → ['robot', 'control', 'timeout']; an empty key means the whole document."""
    return key.split(".") if key else []


class _DuplicateKey(Exception):
    def __init__(self, key: str, line: int, first: int) -> None:
        super().__init__(key)
        self.key, self.line, self.first = key, line, first


def _build(node: yaml.Node, path: KeyPath, lines: dict[KeyPath, int], tags: ScalarTags) -> Any:
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
            result[key] = _build(value_node, child, lines, tags)
        return result
    if isinstance(node, yaml.SequenceNode):
        items = []
        for index, item in enumerate(node.value):
            child = (*path, str(index))
            lines[child] = item.start_mark.line + 1
            items.append(_build(item, child, lines, tags))
        return items
    if isinstance(node, yaml.ScalarNode) and node.tag in tags:
        try:
            return tags[node.tag](node.value)
        except ValueError as error:
            raise yaml.constructor.ConstructorError(None, None, f"{node.tag} {node.value!r}: {error}",
                                                    node.start_mark) from None
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


def _too_big(path: Path, line: int, limit: str, found: str) -> YamlSyntaxError:
    error = YamlSyntaxError(
        f"YAML file too complex: {path.name}",
        what=f"YAML in {path} within plem's limits: {limit}",
        why=f"{path}:{line}: {found}",
        how=f"check that {path} is the file you meant; configuration files never come near this limit",
    )
    error.line = line
    return error


def _line(event: yaml.Event) -> int:
    return event.start_mark.line + 1 if event.start_mark else 1


def _check_shape(text: str, path: Path) -> None:
    """Refuse nesting deeper than MAX_YAML_DEPTH and more than MAX_YAML_VALUES values with aliases expanded.

    One pass over the parser's events, which libyaml produces without recursion, so neither limit can be
    reached before it is checked.
    """
    try:
        _count_values(text, path)
    except yaml.MarkedYAMLError as exc:
        # libyaml 0.2.6 (PyYAML 6.0.4) scans ahead and stops at its own depth limit before the parser hands
        # over the 65th level: the same problem, said the same way.
        if "nesting depth" not in (exc.problem or ""):
            raise
        mark = exc.problem_mark
        raise _too_big(path, mark.line + 1 if mark else 1, f"nesting at most {MAX_YAML_DEPTH} deep",
                       f"collections nest more than {MAX_YAML_DEPTH} deep here") from None


def _count_values(text: str, path: Path) -> None:
    """The pass of `_check_shape` over the parser's events."""
    sizes: dict[str, int] = {}
    open_values: list[tuple[int, str | None]] = [(0, None)]   # values inside each open collection, its anchor
    for event in yaml.parse(text, Loader=_Loader):
        if isinstance(event, yaml.CollectionStartEvent):
            if len(open_values) > MAX_YAML_DEPTH:
                raise _too_big(path, _line(event), f"nesting at most {MAX_YAML_DEPTH} deep",
                               f"collections nest more than {MAX_YAML_DEPTH} deep here")
            open_values.append((0, event.anchor))
            continue
        if isinstance(event, yaml.CollectionEndEvent):
            count, anchor = open_values.pop()
            size = count + 1
        elif isinstance(event, yaml.ScalarEvent):
            size, anchor = 1, event.anchor
        elif isinstance(event, yaml.AliasEvent):
            size, anchor = sizes.get(event.anchor or "", 1), None
        else:
            continue
        if anchor is not None:
            sizes[anchor] = size
        count, parent_anchor = open_values[-1]
        open_values[-1] = (count + size, parent_anchor)
        if open_values[0][0] + sum(c for c, _ in open_values[1:]) > MAX_YAML_VALUES:
            raise _too_big(path, _line(event),
                           f"at most {MAX_YAML_VALUES:,} values with every alias (*name) expanded",
                           "the aliases up to here expand to more values than that (an alias bomb?)")


def parse_yaml(text: str, path: Path, tags: ScalarTags | None = None) -> YamlDocument:
    """Parse `text` read from `path` (with the local scalar `tags` given); syntax problems, duplicate keys and
    exceeded limits become a ConfigError."""
    lines: dict[KeyPath, int] = {}
    try:
        _check_shape(text, path)
        node = yaml.compose(text, Loader=_Loader)
        root = _build(node, (), lines, tags or {}) if node is not None else None
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


def read_yaml(path: Path, role: str = "YAML file", tags: ScalarTags | None = None) -> YamlDocument:
    """Read and parse `path` (as `parse_yaml` does): a regular UTF-8 file of at most MAX_YAML_BYTES, else a
    ConfigError saying which."""
    return parse_yaml(read_regular_text(path, MAX_YAML_BYTES, role), path, tags)


def load_yaml(path: Path, role: str = "YAML file") -> Any:
    """The plain value of the YAML file at `path`, read and checked as `read_yaml` does."""
    return read_yaml(path, role).root
