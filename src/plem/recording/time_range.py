"""`--from`/`--to` of `plem bag plot`: an ISO date and time, a clock time on the recording's day, or seconds
after the recording's start, resolved to ns since the epoch once the recording's extent is known."""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass

from plem.errors import UsageError
from plem.recording.archive import iso_time
from plem.recording.summary import Window

FORMS = ("an ISO date and time (2026-11-24T18:30:05; UTC unless it names its offset), a clock time on the "
         "recording's day (18:30:05 or 18:30:05.250, UTC), or seconds after the recording's start (+12.5)")
_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)


def _ns(moment: dt.datetime) -> int:
    """ns since the epoch of an aware datetime."""
    return (moment - _EPOCH) // dt.timedelta(microseconds=1) * 1000


@dataclass(frozen=True)
class TimePoint:
    """A --from/--to value as given: exactly one of `after_start_ns`, `clock` and `instant_ns` is set."""

    text: str
    after_start_ns: int | None = None
    clock: dt.time | None = None
    instant_ns: int | None = None

    def at(self, span: Window) -> int:
        """ns since the epoch on a recording covering `span`. A clock time is taken on the recording's first day,
        or on the next when only that falls within the recording (one running past midnight)."""
        if self.after_start_ns is not None:
            return span[0] + self.after_start_ns
        if self.clock is not None:
            day = dt.datetime.fromtimestamp(span[0] // 1_000_000_000, dt.UTC).date()
            zone = self.clock.tzinfo or dt.UTC
            moments = [_ns(dt.datetime.combine(day + dt.timedelta(days=later), self.clock.replace(tzinfo=zone)))
                       for later in (0, 1)]
            return next((moment for moment in moments if span[0] <= moment <= span[1]), moments[0])
        assert self.instant_ns is not None
        return self.instant_ns


def parse_time(text: str | None, flag: str) -> TimePoint | None:
    """A --from/--to value (None when not given); UsageError naming the accepted forms when it is none of them."""
    if text is None:
        return None
    value = text.strip()
    try:
        if value.startswith("+"):
            seconds = float(value[1:])
            if not math.isfinite(seconds) or seconds < 0:
                raise ValueError(f"{seconds} is not a number of seconds from 0 on")
            return TimePoint(text, after_start_ns=round(seconds * 1e9))
        try:
            return TimePoint(text, clock=dt.time.fromisoformat(value))
        except ValueError:
            moment = dt.datetime.fromisoformat(value)
            return TimePoint(text, instant_ns=_ns(moment if moment.tzinfo else moment.replace(tzinfo=dt.UTC)))
    except (ValueError, OverflowError) as error:
        raise UsageError(f"{flag} {text!r} is not a time", what=f"{flag} as {FORMS}", why=str(error),
                         how=f"pass e.g. {flag} 18:30:05 or {flag} +12.5") from None


def time_range(start: TimePoint | None, end: TimePoint | None, span: Window | None) -> tuple[int | None, int | None]:
    """--from and --to in ns since the epoch on a recording covering `span` (None: not given, or nothing recorded);
    UsageError when --from comes after --to."""
    if span is None:
        return None, None
    if start is not None and end is not None and start.at(span) > end.at(span):
        raise UsageError(f"--from {start.text} comes after --to {end.text}", what="--from before --to",
                         why=f"--from is {iso_time(start.at(span))}, --to {iso_time(end.at(span))}",
                         how="swap them, or pass a later --to")
    return (None if start is None else start.at(span)), (None if end is None else end.at(span))
