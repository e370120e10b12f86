"""The continuous export (`export_dir:=`): closed segments exported as they close, never the open one; the disk
threshold holds it back (said once); a segment deleted before its export is reported once."""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import numpy as np
import pyarrow.dataset as ds
import pytest

from plem.fleet.continuous import Follower
from plem.fleet.destination import open_destination
from plem.fleet.export import disk_room
from plem.recording.bulk_cdr import raw_payloads
from plem.recording.recorder import Messages, Recorder
from tests.integration.fleet_bags import MS, S, recorder_for, ring_records

START = 1_800_000_000 * S


def record_cycles(recorder: Recorder, first: int, count: int, clock: list[int]) -> None:
    stamps = START + np.arange(first, first + count, dtype=np.int64) * MS
    clock[0] = int(stamps[-1])
    records = ring_records(first, count, 6, np.random.default_rng(first))
    recorder.record([Messages("rt_raw", stamps, raw_payloads(records, stamps, 6))])


def exported(root: Path) -> list[str]:
    segments = root / "segments"
    if not segments.exists():
        return []
    return sorted(ds.dataset(segments, format="parquet", partitioning="hive").to_table().column("segment")
                  .to_pylist())


def test_closed_segments_are_exported_as_they_close_never_the_open_one(tmp_path: Path):
    clock = [START]
    recorder = recorder_for(tmp_path / "bags" / "arm", clock, 6)
    follower = Follower(tmp_path / "bags" / "arm", open_destination(str(tmp_path / "fleet")), 99.0)
    try:
        record_cycles(recorder, 0, 1500, clock)              # one closed segment, one open
        assert follower.step() and exported(tmp_path / "fleet") == ["arm_2027_01_15-08_00_00"]
        record_cycles(recorder, 1500, 1000, clock)
        assert follower.step() and exported(tmp_path / "fleet") == ["arm_2027_01_15-08_00_00",
                                                                    "arm_2027_01_15-08_00_01"]
    finally:
        recorder.close()
    assert follower.step() and len(exported(tmp_path / "fleet")) == 3
    rows = ds.dataset(tmp_path / "fleet" / "rt_raw", format="parquet", partitioning="hive").to_table()
    assert sorted(rows.column("cycle").to_pylist()) == list(range(2500))


def test_the_disk_threshold_holds_the_export_back_and_a_deleted_segment_is_reported_once(
        tmp_path: Path, caplog: pytest.LogCaptureFixture):
    clock = [START]
    robot = tmp_path / "bags" / "arm"
    recorder = recorder_for(robot, clock, 6)
    record_cycles(recorder, 0, 3000, clock)
    recorder.close()
    destination = open_destination(str(tmp_path / "fleet"))
    follower = Follower(robot, destination, 0.0)             # any disk is fuller than 0 %
    with caplog.at_level(logging.INFO, "plem.export"):
        assert not follower.step() and not follower.step()
        held = [record.getMessage() for record in caplog.records if "export held back" in record.getMessage()]
        assert len(held) == 1 and "disk_threshold 0 %" in held[0] and "raise disk_threshold:=" in held[0]
        assert exported(tmp_path / "fleet") == []
        shutil.rmtree(robot / "arm_2027_01_15-08_00_00")     # retention deletes it before its export
        caplog.clear()
        follower.room = disk_room(destination, 100.0)
        assert follower.step() and follower.step()
    assert exported(tmp_path / "fleet") == ["arm_2027_01_15-08_00_01", "arm_2027_01_15-08_00_02"]
    deleted = [record.getMessage() for record in caplog.records if "deleted before its export" in record.getMessage()]
    assert len(deleted) == 1 and "arm_2027_01_15-08_00_00" in deleted[0]


def test_a_destination_that_cannot_be_opened_is_said_once_and_tried_again(tmp_path: Path,
                                                                          caplog: pytest.LogCaptureFixture,
                                                                          monkeypatch: pytest.MonkeyPatch):
    import threading

    from plem.fleet import continuous

    (tmp_path / "file").write_text("")
    waits: list[float] = []
    stop = threading.Event()

    def wait(seconds: float) -> bool:
        waits.append(seconds)
        if len(waits) == 3:
            stop.set()
        return stop.is_set()

    monkeypatch.setattr(stop, "wait", wait)
    with caplog.at_level(logging.INFO, "plem.export"):
        continuous.follow(tmp_path / "bags" / "arm", str(tmp_path / "file"), 99.0, stop)
    said = [record.getMessage() for record in caplog.records if "is not a directory" in record.getMessage()]
    assert len(said) == 1 and waits == [continuous.RETRY_S] * 3
