"""The readouts beside the arm: one line of text per item, sent to the page only when it changes."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import viser

_MARKDOWN = str.maketrans({character: f"\\{character}" for character in "\\`*_{}[]<>()#+-.!|~"})


def plain(text: str) -> str:
    """`text` with Markdown's special characters escaped, so names like free_drive show as written."""
    return text.translate(_MARKDOWN)


class Readouts:
    """A folder of labelled lines on the page."""

    def __init__(self, gui: viser.GuiApi, title: str, labels: Iterable[str], order: float = 0.0) -> None:
        with gui.add_folder(title, order=order):
            self._lines = {label: gui.add_markdown(f"**{label}** —") for label in labels}
        self._shown: dict[str, str] = {}

    def update(self, values: Mapping[str, str]) -> None:
        """Show these values; lines not given keep theirs."""
        for label, value in values.items():
            if label in self._lines and self._shown.get(label) != value:
                self._lines[label].content = f"**{label}** {plain(value)}"
                self._shown[label] = value
