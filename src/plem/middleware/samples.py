"""Samples a subscription drops (too large, or not decodable as its type), said in words, one line at a time.

Anyone on the DDS domain can write any bytes to any topic, so a sample that does not decode is the sender's
mistake, never a failure of the reader: it is dropped, the samples beside it are still handled, and the log
says which endpoint dropped what and why. A flood of bad samples gives one line per `WARNING_PERIOD_S`, with
the count of those not said since.
"""

from __future__ import annotations

import logging
import struct
import time

_log = logging.getLogger("plem.dds")
#: At most one warning per endpoint this often; the drops between are counted in the next one.
WARNING_PERIOD_S = 1.0


def undecodable(error: Exception) -> str:
    """Why a sample did not decode, in words: the serializer's own exceptions name no field and no rule."""
    if isinstance(error, UnicodeDecodeError):
        return (f"a string in it is not valid UTF-8 (byte 0x{error.object[error.start]:02x} at {error.start} of "
                "the string)")
    if isinstance(error, (struct.error, IndexError, EOFError)):
        return "it ends before its last field (a length or a field is cut short)"
    if isinstance(error, MemoryError):
        return "a length in it is larger than any sample can hold"
    return f"it is not a valid sample of the topic's type ({type(error).__name__}: {str(error)[:120]})"


class SampleDrops:
    """Counts the samples one endpoint dropped and says why, at most once per WARNING_PERIOD_S."""

    def __init__(self, endpoint: str) -> None:
        self.endpoint = endpoint
        self.dropped = 0
        self._unsaid = 0
        self._next_warning = 0.0

    def drop(self, reason: str) -> None:
        """Count one dropped sample; warn now unless a warning was given within the period."""
        self.dropped += 1
        now = time.monotonic()
        if now < self._next_warning:
            self._unsaid += 1
            return
        more = f"; {self._unsaid} more dropped since the last warning" if self._unsaid else ""
        _log.warning("the %s dropped a sample: %s%s", self.endpoint, reason, more)
        self._unsaid, self._next_warning = 0, now + WARNING_PERIOD_S
