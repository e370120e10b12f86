"""Flags in `--help` as flags: typer shows every option's value type, so a flag such as `--watch` would read
`--watch <bool>` as if it took a value, which it does not (`plem --version true` is refused, see app.py)."""

from __future__ import annotations

from typer._click import Context
from typer.core import TyperOption

_typed_display = TyperOption.display_type_rich


def _display_type(option: TyperOption, ctx: Context) -> str | None:
    """No value type for an on/off flag; typer's display for every other option."""
    if option.is_flag and not option.count:
        return None
    return _typed_display(option, ctx)


def install() -> None:
    """Have typer's help show flags without a value type."""
    TyperOption.display_type_rich = _display_type  # type: ignore[method-assign, assignment]  # typer has no setting
