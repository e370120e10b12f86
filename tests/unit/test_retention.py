"""Retention and disk-guard choices with an injected clock and disk usage."""

from __future__ import annotations

from plem.recording.retention import Segment, choose_deletions, deletable

MIN = 60 * 10**9


def segments(count: int, size: int = 100, protected: frozenset[int] = frozenset()) -> list[Segment]:
    """`count` one-minute segments, the first starting at t = 0."""
    return [Segment(f"s{i}", i * MIN, (i + 1) * MIN, size, i in protected) for i in range(count)]


def test_segments_older_than_retention_go_oldest_first():
    chosen = choose_deletions(segments(10), now_ns=10 * MIN, retention_ns=5 * MIN, threshold_percent=70,
                              disk_percent=lambda freed: 10.0)
    assert [d.segment.path for d in chosen] == ["s0", "s1", "s2", "s3"]   # s4 ended exactly 5 min ago
    assert all("retention" in d.reason for d in chosen)


def test_nothing_goes_inside_retention_and_below_threshold():
    assert choose_deletions(segments(3), now_ns=3 * MIN, retention_ns=60 * MIN, threshold_percent=70,
                            disk_percent=lambda freed: 69.9) == []


def test_a_full_disk_removes_oldest_until_below_threshold():
    usage = lambda freed: 90.0 - freed / 100   # noqa: E731 - each 100-byte segment frees 1 %
    chosen = choose_deletions(segments(30), now_ns=30 * MIN, retention_ns=60 * MIN, threshold_percent=70,
                              disk_percent=usage)
    assert [d.segment.path for d in chosen] == [f"s{i}" for i in range(20)]
    assert "disk 90.0 % full" in chosen[0].reason and "disk_threshold 70 %" in chosen[0].reason


def test_protected_segments_and_the_newest_survive_both_rules():
    chosen = choose_deletions(segments(10, protected=frozenset({1, 2})), now_ns=100 * MIN, retention_ns=MIN,
                              threshold_percent=0, disk_percent=lambda freed: 99.0)
    assert {d.segment.path for d in chosen} == {f"s{i}" for i in range(9)} - {"s1", "s2"}


def test_room_other_files_took_is_not_made_by_deleting_segments():
    """Deleting all 29 deletable segments (29 %) cannot bring a 99.5 % disk below 70 %: none goes."""
    usage = lambda freed: 99.5 - freed / 100   # noqa: E731 - each 100-byte segment frees 1 %
    assert choose_deletions(segments(30), now_ns=30 * MIN, retention_ns=60 * MIN, threshold_percent=70,
                            disk_percent=usage) == []


def test_retention_still_applies_when_other_files_fill_the_disk():
    chosen = choose_deletions(segments(10), now_ns=10 * MIN, retention_ns=5 * MIN, threshold_percent=70,
                              disk_percent=lambda freed: 99.0)
    assert [d.segment.path for d in chosen] == ["s0", "s1", "s2", "s3"]
    assert all("retention" in d.reason for d in chosen)


def test_deletable_leaves_out_the_newest_and_the_protected():
    assert [s.path for s in deletable(segments(5, protected=frozenset({1})))] == ["s0", "s2", "s3"]
