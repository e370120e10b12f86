"""`plem launch bus:=mock export_dir:=DIR`: the recorder's closed segments reach the dataset while the robot runs,
and the last one once the launch stops; each says who recorded it."""

from __future__ import annotations

import os
from pathlib import Path

import pyarrow.dataset as ds

from plem.bridge import connect
from plem.recording.summary import find_bags, robot_segments
from tests.e2e.launched import clean_environment, launched, new_robot_id, wait_until


def exported(root: Path) -> list[dict[str, object]]:
    if not (root / "segments").exists():
        return []
    return ds.dataset(root / "segments", format="parquet", partitioning="hive").to_table().to_pylist()


def test_a_launched_robot_exports_its_closed_segments(tmp_path: Path):
    robot_id, bags, fleet = new_robot_id(), tmp_path / "bags", tmp_path / "fleet"
    arguments = ["bus:=mock", f"robot_id:={robot_id}", f"bag_dir:={bags}", "bag_segment_seconds:=1",
                 "bridge:=false", "planner:=false", f"export_dir:={fleet}"]
    with launched(arguments, [robot_id], tmp_path, clean_environment(tmp_path / "home")) as launch:
        with connect(robot_id) as client:
            client.set_mode("hold")
            assert wait_until(lambda: len(exported(fleet)) >= 2, timeout=60, period=0.2), launch.output
            open_segments = [path.name for path in (bags / robot_id).iterdir() if (path / ".reserve").exists()]
            assert open_segments and not {row["segment"] for row in exported(fleet)} & set(open_segments)
            assert f"[export] INFO: exported {robot_id}/" in launch.errors, "the launch shows what was exported"
        assert launch.stop() == 0
    segments = robot_segments(find_bags(bags / robot_id)[0])
    rows = {str(row["segment"]): row for row in exported(fleet)}
    assert sorted(rows) == [segment.name for segment in segments], "every segment, the last one at the stop"
    for segment in segments:
        row = rows[segment.name]
        assert row["rt_raw_rows"] == segment.topics[f"/{robot_id}/rt_raw"][1]
        assert row["host"] == os.uname().nodename and row["model"] == "Indy7V2" and row["dof"] == 6
        assert row["joint_names"] == [f"joint{index}" for index in range(6)] and row["serial"] is None
    raw = ds.dataset(fleet / "rt_raw", format="parquet", partitioning="hive").to_table()
    cycles = sorted(raw.column("cycle").to_pylist())
    assert cycles == list(range(1, len(cycles) + 1)), "every recorded cycle once"
