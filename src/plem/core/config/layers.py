"""Layered configuration: the highest layer that sets a field wins, and the winner is remembered.

The layers, highest first, are those of the configuration reference: programmatic, launch arguments,
environment variables, robot profile, model defaults.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any


class LayerKind(IntEnum):
    """Precedence of a layer; a larger value wins."""

    MODEL_DEFAULT = 0
    LAUNCH_DEFAULT = 1
    PROFILE = 2
    ENVIRONMENT = 3
    LAUNCH_ARGUMENT = 4
    PROGRAMMATIC = 5


@dataclass(frozen=True)
class Source:
    """Where a field's effective value came from, e.g. `environment PLEM_RT_PRIORITY`."""

    kind: LayerKind
    detail: str

    def __str__(self) -> str:
        return self.detail


@dataclass
class Layer:
    """Values one layer provides, each with the source text to show for it."""

    kind: LayerKind
    values: dict[str, tuple[Any, Source]] = field(default_factory=dict)

    def set(self, name: str, value: Any, detail: str) -> None:
        """Provide `value` for field `name`, with `detail` saying where in this layer it came from."""
        self.values[name] = (value, Source(self.kind, detail))


def merge_layers(layers: Iterable[Layer]) -> dict[str, tuple[Any, Source]]:
    """For every field any layer sets, the value and source of the highest such layer."""
    merged: dict[str, tuple[Any, Source]] = {}
    for layer in sorted(layers, key=lambda candidate: candidate.kind):
        merged.update(layer.values)
    return merged
