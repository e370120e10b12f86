"""A child process's stderr, passed on to the launch's own and remembered, so the launch can say why it died.

A component logs its warnings and errors on stderr; the launch forwards every line as it comes (the user sees
them as before) and keeps the last one that names an error, which is what the launch prints when the
component ends unexpectedly.
"""

from __future__ import annotations

import re
import sys
import threading
from typing import IO, TextIO

#: A line that says something went wrong: a log record's level, or the last line of a traceback.
_ERROR = re.compile(r"\b(ERROR|CRITICAL|FATAL)\b|^\w+(\.\w+)*(Error|Exception|Interrupt|Exit)\b")
#: Characters of a line kept for the launch's message.
LINE_CHARACTERS = 400
_write_lock = threading.Lock()


class ErrorTail:
    """Forwards one child's stderr line by line (from a thread of its own) and keeps its last error line."""

    def __init__(self, stream: IO[str], sink: TextIO | None = None) -> None:
        self._stream = stream
        self._sink = sink
        self._last_error = ""
        self._last_line = ""
        self._thread = threading.Thread(target=self._forward, name="plem-child-stderr", daemon=True)
        self._thread.start()

    def _forward(self) -> None:
        sink = self._sink or sys.stderr
        for line in self._stream:
            with _write_lock:   # whole lines: several children write at once
                try:
                    sink.write(line)
                    sink.flush()
                except (OSError, ValueError):   # the launch's stderr is gone: keep reading, so the child never blocks
                    pass
            text = line.strip()
            if text:
                self._last_line = text[:LINE_CHARACTERS]
                if _ERROR.search(text):
                    self._last_error = self._last_line

    def last_error(self, timeout: float = 1.0) -> str:
        """The last error line the child printed (else its last line, else ""), once its stderr is read to the end
        (at most `timeout` s after it died)."""
        self._thread.join(timeout)
        return self._last_error or self._last_line
