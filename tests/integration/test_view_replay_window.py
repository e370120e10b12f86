"""`plem view --bag DIR --fault N` reads the fault's window of the bags, not the whole recording."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from plem.recording import timeline
from plem.recording.summary import Payloads
from plem.view.replay import Replay
from tests.integration.test_bag_cli import START, record

S = 1_000_000_000


def test_opening_at_a_fault_reads_rt_raw_only_from_the_segments_of_its_window(tmp_path: Path,
                                                                             monkeypatch: pytest.MonkeyPatch):
    """15 s of 1 s segments with a fault at 1.7 s (a 10 s flight window, 2 s after it): segments starting after
    3.7 s are never read for rt_raw, and the replay shows the window at full rate."""
    record(tmp_path / "arm", samples=15_000)
    reads: list[tuple[str, str]] = []
    read_topic = timeline.read_topic

    def counted(path: Path, topic: str, *arguments: object, **options: object) -> Iterator[Payloads]:
        reads.append((path.name, topic))
        return read_topic(path, topic, *arguments, **options)       # type: ignore[arg-type]

    monkeypatch.setattr(timeline, "read_topic", counted)
    replay = Replay.of_bags(tmp_path, "arm", fault=1)
    raw_segments = sorted({segment for segment, topic in reads if topic.endswith("/rt_raw")})
    assert replay.fault is not None and replay.fault.time_ns == START + 1700 * 1_000_000
    assert len(raw_segments) == 4, raw_segments                      # 0..1 s, 1..2 s, 2..3 s, 3..4 s
    assert replay.timeline.time_ns[-1] <= START + 3700 * 1_000_000
    assert len(replay.timeline.time_ns) == 3701 and replay.timeline.description      # both ends included
    replay.focus(None)                                               # the whole recording, read when asked for
    assert replay.timeline.time_ns[-1] == START + 14_999 * 1_000_000
