"""ConfigLoader: typed values from YAML files by dotted key, cached per file until the file changes."""

from __future__ import annotations

import contextlib
import os
import threading
from pathlib import Path
from typing import Any, TypeVar, get_args, overload

from plem.core.config.yaml_document import YamlDocument, read_yaml
from plem.core.paths import resolve_resource
from plem.errors import ConfigError

T = TypeVar("T")
U = TypeVar("U")
_MISSING: Any = object()
#: A YAML file: absolute, relative to the working directory, or package/relative.
ConfigPath = str | os.PathLike[str]


def _type_name(as_type: Any) -> str:
    return str(as_type).replace("typing.", "") if get_args(as_type) else getattr(as_type, "__name__", str(as_type))


class ConfigLoader:
    """Loads YAML configuration; one shared instance caches parsed files keyed by path and stat."""

    _instance: ConfigLoader | None = None
    _instance_lock = threading.Lock()

    def __init__(self) -> None:
        self._cache: dict[Path, tuple[tuple[int, int, int], YamlDocument]] = {}
        self._lock = threading.Lock()

    @classmethod
    def get_instance(cls) -> ConfigLoader:
        """The process-wide loader (its cache is shared by every caller)."""
        with cls._instance_lock:
            if cls._instance is None:
                cls._instance = cls()
            return cls._instance

    def document(self, path: str | os.PathLike[str]) -> YamlDocument:
        """The parsed file at `path` (absolute, relative, or package/relative), re-read if it changed."""
        try:
            resolved = resolve_resource(path).resolve()
        except (OSError, ValueError) as error:   # a name the OS rejects: too long, a NUL byte
            raise ConfigError(f"Cannot use the path {str(path)[:80]!r}", what="a YAML file path the system accepts",
                              why=getattr(error, "strerror", None) or str(error),
                              how="check the path: each part at most 255 characters, no NUL bytes") from None
        try:
            st = resolved.stat()
        except OSError:
            st = None
        signature = (st.st_mtime_ns, st.st_size, st.st_ino) if st else (0, 0, 0)
        with self._lock:
            cached = self._cache.get(resolved)
            if cached and cached[0] == signature:
                return cached[1]
        document = read_yaml(resolved)
        with self._lock:
            self._cache[resolved] = (signature, document)
        return document

    def invalidate(self, path: str | os.PathLike[str] | None = None) -> None:
        """Forget one cached file, or all of them."""
        with self._lock:
            if path is None:
                self._cache.clear()
            else:
                self._cache.pop(Path(path).resolve(), None)

    @overload
    def load(self, path: ConfigPath, key: str = "") -> Any: ...
    @overload
    def load(self, path: ConfigPath, key: str = "", as_type: type[T] = ...) -> T: ...
    @overload
    def load(self, path: ConfigPath, key: str = "", as_type: Any = ...) -> Any: ...
    def load(self, path: ConfigPath, key: str = "", as_type: Any = Any) -> Any:
        """The value at dotted `key` (whole document when empty), checked against `as_type`."""
        document = self.document(path)
        node, line = document.lookup(key)
        return _check_type(document, key, line, node, as_type)

    @overload
    def load_optional(self, path: ConfigPath, key: str) -> Any | None: ...
    @overload
    def load_optional(self, path: ConfigPath, key: str, as_type: type[T]) -> T | None: ...
    @overload
    def load_optional(self, path: ConfigPath, key: str, as_type: Any) -> Any | None: ...
    def load_optional(self, path: ConfigPath, key: str, as_type: Any = Any) -> Any | None:
        """Like `load`, but None when the key is absent. A missing file or a wrong type is still an error."""
        found = self._find(path, key)
        return None if found is None else _check_type(*found, as_type)

    @overload
    def load_or_default(self, path: ConfigPath, default: None, key: str = "") -> Any: ...
    @overload
    def load_or_default(self, path: ConfigPath, default: T, key: str = "") -> T: ...
    @overload
    def load_or_default(self, path: ConfigPath, default: T, key: str, as_type: type[U]) -> T | U: ...
    @overload
    def load_or_default(self, path: ConfigPath, default: Any, key: str, as_type: Any) -> Any: ...
    def load_or_default(self, path: ConfigPath, default: Any, key: str = "", as_type: Any = _MISSING) -> Any:
        """The value at `key`, or `default` when the key is absent; the type defaults to the default's type."""
        if as_type is _MISSING:
            as_type = Any if default is None else type(default)
        found = self._find(path, key)
        return default if found is None else _check_type(*found, as_type)

    def _find(self, path: ConfigPath, key: str) -> tuple[YamlDocument, str, int, Any] | None:
        """The document, key, line and node of `key`, or None when the file has no such key."""
        document = self.document(path)
        try:
            node, line = document.lookup(key)
        except ConfigError:
            return None
        return document, key, line, node


def _check_type(document: YamlDocument, key: str, line: int | None, value: Any, as_type: Any) -> Any:
    if as_type is Any:
        return value
    from pydantic import TypeAdapter, ValidationError  # deferred: costs 70 ms and only typed loads need it

    try:
        return TypeAdapter(as_type).validate_python(value, strict=True)
    except ValidationError as exc:
        first = exc.errors()[0]
        location = ".".join(str(p) for p in first["loc"])
        item_key = f"{key}.{location}" if location else key
        item_line = line
        if location:
            with contextlib.suppress(ConfigError):
                item_line = document.lookup(item_key)[1]
        shown = repr(first.get("input", value))
        raise ConfigError(
            f"Wrong type for '{key or '(document)'}' in {document.path.name}",
            what=f"'{key or '(document)'}' as {_type_name(as_type)}",
            why=f"{document.path}:{item_line}: '{item_key or '(document)'}' is {shown} ({first['msg'].lower()})",
            how=f"change the value at {document.path}:{item_line} to a {_type_name(as_type)}",
        ) from None


@overload
def load_config(path: ConfigPath, key: str = "") -> Any: ...
@overload
def load_config(path: ConfigPath, key: str = "", as_type: type[T] = ...) -> T: ...
@overload
def load_config(path: ConfigPath, key: str = "", as_type: Any = ...) -> Any: ...
def load_config(path: ConfigPath, key: str = "", as_type: Any = Any) -> Any:
    """The value at `key` in the YAML file at `path`, e.g. `load_config("c.yaml", "rt_priority", int)`."""
    return ConfigLoader.get_instance().load(path, key, as_type)


@overload
def load_config_optional(path: ConfigPath, key: str) -> Any | None: ...
@overload
def load_config_optional(path: ConfigPath, key: str, as_type: type[T]) -> T | None: ...
@overload
def load_config_optional(path: ConfigPath, key: str, as_type: Any) -> Any | None: ...
def load_config_optional(path: ConfigPath, key: str, as_type: Any = Any) -> Any | None:
    """The value at `key`, or None when the key is absent."""
    return ConfigLoader.get_instance().load_optional(path, key, as_type)
