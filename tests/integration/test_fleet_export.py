"""`plem bag export`: bags recorded by the recorder's own code paths, exported to a Parquet dataset and read back
with pyarrow and DuckDB; every value equals rosbags' deserialisation; reruns, kills at every file boundary, a
real S3 server (moto), bags of an older plem, and the WHAT/WHY/HOW errors."""

from __future__ import annotations

import os
import secrets
import shutil
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import duckdb
import numpy as np
import pyarrow as pa
import pyarrow.dataset as ds
import pyarrow.parquet as pq
import pytest
from rosbags.highlevel import AnyReader

from plem.fleet import schema
from plem.fleet.destination import DestinationError, open_destination
from plem.fleet.export import export
from plem.recording.segment import SegmentWriter
from tests.e2e.cli import plem_executable, run_plem
from tests.integration.fleet_bags import MS, STORE, S, joints, record_old_raw, record_robot
from tests.local_servers import moto_server

DAY = 86_400 * S
MIDNIGHT = 1_800_057_600 * S                    # 2027-01-16T00:00:00Z
#: arm_a: 2.5 s across midnight (a segment spanning it); arm_b: a 7-axis arm, 2 s with 3 cycles lost.
ROBOTS = {"arm_a": dict(start_ns=MIDNIGHT - 1_500 * MS, cycles=2500, dof=6, seed=1),
          "arm_b": dict(start_ns=MIDNIGHT + 3_600 * S, cycles=2000, dof=7, seed=2, lost_after=1500)}


@pytest.fixture(scope="module")
def bag_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A bag_dir of two robots."""
    directory = tmp_path_factory.mktemp("bags")
    for robot_id, options in ROBOTS.items():
        record_robot(directory / robot_id, **options)
    return directory


@pytest.fixture(scope="module")
def dataset(bag_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    destination = tmp_path_factory.mktemp("fleet") / "dataset"
    result = run_plem("bag", "export", str(bag_dir), "--to", str(destination))
    assert result.returncode == 0, result.stderr
    assert "exported 5 segments (4500 rt_raw rows" in result.stdout
    return destination


def files(root: Path) -> dict[str, bytes]:
    """Every file under a dataset, by relative path."""
    return {str(path.relative_to(root)): path.read_bytes() for path in sorted(root.rglob("*")) if path.is_file()}


def table(root: Path, name: str) -> pa.Table:
    return ds.dataset(root / name, format="parquet", partitioning="hive").to_table()


def test_the_dataset_layout_is_hive_partitioned_by_robot_and_utc_date(dataset: Path):
    names = set(files(dataset))
    assert "rt_raw/robot_id=arm_a/date=2027-01-15/arm_a_2027_01_15-23_59_58.parquet" in names
    # the segment from 23:59:59.5 holds rows of both dates: one file each
    assert {"rt_raw/robot_id=arm_a/date=2027-01-15/arm_a_2027_01_15-23_59_59.parquet",
            "rt_raw/robot_id=arm_a/date=2027-01-16/arm_a_2027_01_15-23_59_59.parquet"} <= names
    assert "segments/robot_id=arm_b/date=2027-01-16/arm_b_2027_01_16-01_00_00.parquet" in names
    assert all(name.endswith(".parquet") and name.split("/")[0] in schema.TABLES for name in names)
    for name in names:
        metadata = pq.read_metadata(dataset / name).metadata
        assert metadata[schema.VERSION_KEY] == str(schema.SCHEMA_VERSION).encode()


def test_duckdb_reads_every_row_once_with_its_robot_and_date(dataset: Path):
    rows = duckdb.sql(f"SELECT robot_id, count(*), count(DISTINCT cycle), min(time)::DATE, max(time)::DATE, "
                      f"count(speed_override), bool_and(date = time::DATE) FROM read_parquet('{dataset}/rt_raw/**/"
                      "*.parquet', hive_partitioning = true, union_by_name = true) GROUP BY robot_id ORDER BY 1"
                      ).fetchall()
    assert [row[:3] for row in rows] == [("arm_a", 2500, 2500), ("arm_b", 2000, 2000)]
    assert rows[0][3:] == (np.datetime64("2027-01-15").astype(object), np.datetime64("2027-01-16").astype(object),
                           2500, True)
    seventh = duckdb.sql(f"SELECT robot_id, count(position_6) FROM read_parquet('{dataset}/rt_raw/**/*.parquet', "
                         "hive_partitioning = true, union_by_name = true) GROUP BY 1 ORDER BY 1").fetchall()
    assert seventh == [("arm_a", 0), ("arm_b", 2000)]
    fault = duckdb.sql(f"SELECT robot_id, kind, reason FROM read_parquet('{dataset}/rt_events/**/*.parquet', "
                       "hive_partitioning = true) ORDER BY 1").fetchall()
    assert fault == [(robot, "fault", "joint2: drive fault 0x7121 (following error)") for robot in ROBOTS]


def test_the_segments_table_says_who_recorded_what(dataset: Path):
    rows = {row["segment"]: row for row in table(dataset, "segments").to_pylist()}
    assert len(rows) == 5
    b = [row for name, row in sorted(rows.items()) if name.startswith("arm_b")]
    assert [row["rt_raw_rows"] for row in b] == [1000, 1000] and [row["dropped"] for row in b] == [0, 3]
    for row in rows.values():
        assert row["serial"] == "PE07I7E0E001" and row["model"] == "Indy7V2" and row["host"] == os.uname().nodename
        assert row["plem_version"] and row["schema_version"] == schema.SCHEMA_VERSION
        assert row["joint_names"] == joints(row["dof"]) and row["start"] < row["end"]
        assert row["joint_states_rows"] == row["rt_raw_rows"] // 10
        assert row["rt_monitor_stats_rows"] >= 1


def rosbags_messages(segment: Path, topic: str) -> list[tuple[int, Any]]:
    """Every message of a topic as rosbags deserialises it, through the definitions the bag embeds."""
    with AnyReader([segment]) as reader:
        connections = [c for c in reader.connections if c.topic.endswith(f"/{topic}")]
        return [(stamp, reader.deserialize(data, connection.msgtype))
                for connection, stamp, data in reader.messages(connections=connections)]


def segment_rows(dataset: Path, name: str, robot_id: str, segment: str) -> pa.Table:
    parts = sorted((dataset / name / f"robot_id={robot_id}").glob(f"*/{segment}.parquet"))
    return pa.concat_tables([pq.read_table(part) for part in parts])


def test_every_value_equals_rosbags_deserialisation(bag_dir: Path, dataset: Path):
    for robot_id, options in ROBOTS.items():
        dof = options["dof"]
        for segment in sorted(path for path in (bag_dir / robot_id).iterdir() if path.is_dir()):
            rows = segment_rows(dataset, "rt_raw", robot_id, segment.name)
            raw = rows.to_pydict()
            messages = rosbags_messages(segment, "rt_raw")
            assert len(messages) == len(raw["cycle"]) > 0
            assert rows.column("time").cast(pa.int64()).to_pylist() == [stamp for stamp, _ in messages]
            assert [stamp for stamp, _ in messages] == [m.header.stamp.sec * S + m.header.stamp.nanosec
                                                        for _, m in messages]
            for name in ("cycle", "monotonic_ns", "mode", "faulted", "drives_enabled", "latency_ns", "compute_ns",
                         "speed_override"):
                assert raw[name] == [getattr(message, name) for _, message in messages], name
            for row in schema.RAW_JOINT_FIELDS:
                for joint in range(dof):
                    assert raw[f"{row}_{joint}"] == [getattr(message, row)[joint] for _, message in messages]
            states = segment_rows(dataset, "joint_states", robot_id, segment.name).to_pydict()
            messages = rosbags_messages(segment, "joint_states")
            assert all(list(message.name) == joints(dof) for _, message in messages)
            for row in schema.STATE_JOINT_FIELDS:
                for joint in range(dof):
                    assert states[f"{row}_{joint}"] == [getattr(message, row)[joint] for _, message in messages]
            stats = segment_rows(dataset, "rt_monitor_stats", robot_id, segment.name).to_pylist()
            messages = rosbags_messages(segment, "rt_monitor_stats")
            assert len(stats) == len(messages)
            for row, (_, message) in zip(stats, messages, strict=True):
                assert row["cycles"] == message.cycles and row["latency_p999_us"] == message.latency.p999_us
                assert row["queues"] == [{"name": q.name, "capacity": q.capacity, "fill": q.fill,
                                          "written": q.written, "dropped": q.dropped} for q in message.queues]


def test_a_rerun_skips_what_was_exported_and_rewrites_nothing(bag_dir: Path, dataset: Path):
    before = {path: path.stat().st_mtime_ns for path in dataset.rglob("*.parquet")}
    report = export([bag_dir / "arm_a", bag_dir / "arm_b" / "arm_b_2027_01_16-01_00_00"],
                    open_destination(str(dataset)))
    assert report.exported == [] and len(report.already) == 4
    assert {path: path.stat().st_mtime_ns for path in dataset.rglob("*.parquet")} == before


#: Runs the export in a process that kills itself (SIGKILL) at the K-th rename into the dataset: before it
#: (a temporary file is left) or right after it.
_KILLER = """
import os, signal, sys
from pathlib import Path
count, when = [0], sys.argv[3]
real = os.replace
def replace(source, target):
    count[0] += 1
    if count[0] == int(sys.argv[4]) and when == "before":
        os.kill(os.getpid(), signal.SIGKILL)
    real(source, target)
    if count[0] == int(sys.argv[4]) and when == "after":
        os.kill(os.getpid(), signal.SIGKILL)
os.replace = replace
from plem.fleet.destination import open_destination
from plem.fleet.export import export
export([Path(sys.argv[1])], open_destination(sys.argv[2]))
"""


def test_a_kill_at_every_file_boundary_then_a_rerun_gives_the_same_dataset(bag_dir: Path, tmp_path: Path):
    """arm_b's segment with the fault exported whole (a file per table), then killed at each rename in turn: a
    rerun removes the temporary file left and gives the same files, byte for byte."""
    bags = bag_dir / "arm_b" / "arm_b_2027_01_16-01_00_01"
    export([bags], open_destination(str(tmp_path / "reference")))
    reference = files(tmp_path / "reference")
    for k in range(1, len(reference) + 1):
        for when in ("before", "after"):
            destination = tmp_path / f"{when}_{k}"
            killed = subprocess.run([sys.executable, "-c", _KILLER, str(bags), str(destination), when, str(k)],
                                    capture_output=True, text=True, timeout=120)
            assert killed.returncode == -signal.SIGKILL, killed.stderr
            left = files(destination)
            assert len([name for name in left if name.endswith(".parquet")]) == k - (when == "before")
            assert (when == "before") == any(".tmp-" in name for name in left)
            rerun = export([bags], open_destination(str(destination)))
            assert len(rerun.removed_temporaries) == (when == "before")
            assert files(destination) == reference, f"killed {when} rename {k}"
            assert export([bags], open_destination(str(destination))).already == [f"arm_b/{bags.name}"]
            shutil.rmtree(destination)


def test_bags_of_an_older_plem_export_with_nulls_for_what_they_lack(tmp_path: Path):
    record_old_raw(tmp_path / "bags" / "old", MIDNIGHT, 1500)
    report = export([tmp_path / "bags"], open_destination(str(tmp_path / "fleet")))
    assert report.problems == [] and report.rt_raw_rows == 1500
    raw = table(tmp_path / "fleet", "rt_raw")
    assert raw.column("speed_override").null_count == 1500 and raw.column("cycle").to_pylist() == list(range(1500))
    [row] = table(tmp_path / "fleet", "segments").to_pylist()
    assert (row["serial"], row["model"], row["host"], row["plem_version"], row["joint_names"]) == (None,) * 5
    assert row["dof"] == 6 and row["rt_raw_rows"] == 1500


def test_a_killed_segment_is_skipped_with_the_fix_and_the_rest_exported(bag_dir: Path, tmp_path: Path):
    bags = tmp_path / "bags"
    shutil.copytree(bag_dir / "arm_b", bags / "arm_b")
    killed = bags / "arm_b" / "arm_b_2027_01_16-01_00_01"
    (killed / "metadata.yaml").unlink()
    result = run_plem("bag", "export", str(bags), "--to", str(tmp_path / "fleet"))
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert "ERROR: segment arm_b_2027_01_16-01_00_01 not exported: unfinished (recorder killed)" in result.stderr
    assert f"HOW: run `plem bag repair {killed}`, then export again" in result.stderr
    assert "exported 1 segment (1000 rt_raw rows" in result.stdout
    assert run_plem("bag", "repair", str(bags)).returncode == 0
    again = run_plem("bag", "export", str(bags), "--to", str(tmp_path / "fleet"))
    assert again.returncode == 0 and "exported 1 segment" in again.stdout and "1 exported before" in again.stdout


def test_a_segment_being_recorded_is_left_for_a_later_run(tmp_path: Path):
    robot = tmp_path / "bags" / "arm"
    robot.mkdir(parents=True)
    writer = SegmentWriter(robot / "arm_2027_01_16-00_00_00", [("/arm/rt_raw", "plem_msgs/msg/RtRaw")], STORE)
    try:
        result = run_plem("bag", "export", str(tmp_path / "bags"), "--to", str(tmp_path / "fleet"))
        assert result.returncode == 0, result.stderr
        assert "arm/arm_2027_01_16-00_00_00: being recorded, exported once closed" in result.stdout
        assert not list((tmp_path / "fleet").rglob("*.parquet"))
    finally:
        writer.close()


def test_destination_errors_are_what_why_how(bag_dir: Path, tmp_path: Path):
    (tmp_path / "file").write_text("")
    cases = {str(tmp_path / "file"): f"ERROR: {tmp_path / 'file'} is not a directory",
             str(tmp_path / "file" / "sub"): f"ERROR: cannot write the dataset into {tmp_path / 'file' / 'sub'}",
             "s3://": "ERROR: s3:// names no bucket"}
    for destination, summary in cases.items():
        result = run_plem("bag", "export", str(bag_dir), "--to", destination)
        assert result.returncode == 1 and summary in result.stderr and "HOW: " in result.stderr
        assert "Traceback" not in result.stderr
    if os.geteuid() != 0:
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(DestinationError) as error:
            open_destination(str(locked / "fleet"))
        assert "Permission denied" in error.value.why


def test_missing_s3_credentials_are_what_why_how(bag_dir: Path, tmp_path: Path):
    environment = {name: value for name, value in os.environ.items() if not name.startswith("AWS_")}
    environment["HOME"] = str(tmp_path)
    result = subprocess.run([plem_executable(), "bag", "export", str(bag_dir), "--to", "s3://fleet/x"],
                            capture_output=True, text=True, env=environment, timeout=60)
    assert result.returncode == 1 and "ERROR: no S3 credentials for s3://fleet/x" in result.stderr
    assert "HOW: export AWS_ACCESS_KEY_ID=" in result.stderr and "Traceback" not in result.stderr


@pytest.fixture
def s3_server(monkeypatch: pytest.MonkeyPatch) -> Any:
    """A real S3-compatible server (moto's server mode) on a free local port, with the usual AWS variables."""
    with moto_server() as environment:
        for name, value in environment.items():
            monkeypatch.setenv(name, value)
        yield environment


def test_export_to_a_real_s3_server_equals_the_local_export(bag_dir: Path, dataset: Path, s3_server: Any):
    import s3fs

    store = s3fs.S3FileSystem(client_kwargs={"endpoint_url": s3_server["AWS_ENDPOINT_URL"]})
    bucket = f"fleet-{secrets.token_hex(4)}"   # moto keeps buckets per process, across its servers: a fresh name
    result = run_plem("bag", "export", str(bag_dir), "--to", f"s3://{bucket}/plant1", env=s3_server)
    assert result.returncode == 1 and f"ERROR: bucket {bucket} does not exist" in result.stderr
    assert f"HOW: create it (aws s3 mb s3://{bucket})" in result.stderr and "Traceback" not in result.stderr
    store.mkdir(bucket)
    result = run_plem("bag", "export", str(bag_dir), "--to", f"s3://{bucket}/plant1", env=s3_server)
    assert result.returncode == 0, result.stderr
    assert "exported 5 segments (4500 rt_raw rows" in result.stdout
    store.invalidate_cache()
    objects = {key.removeprefix(f"{bucket}/plant1/"): store.cat_file(key) for key in store.find(f"{bucket}/plant1")}
    assert objects == files(dataset)
    raw = ds.dataset(f"{bucket}/plant1/rt_raw", filesystem=store, format="parquet", partitioning="hive").to_table()
    assert raw.num_rows == 4500 and set(raw.column("robot_id").to_pylist()) == set(ROBOTS)
    again = export([bag_dir], open_destination(f"s3://{bucket}/plant1"))
    assert again.exported == [] and len(again.already) == 5


def test_sqlite3_bags_and_joint_states_of_another_shape_export_too(tmp_path: Path):
    """A sqlite3 bag (no embedded definitions: plem's interfaces decode it) whose joint_states carry positions
    only: those messages take the one-by-one path, their missing velocities and efforts are null."""
    from tests.integration.test_bag_cli import record as record_sqlite3

    record_sqlite3(tmp_path / "bags" / "arm", storage="sqlite3", samples=1500)
    report = export([tmp_path / "bags"], open_destination(str(tmp_path / "fleet")))
    assert report.problems == [] and report.rt_raw_rows == 1500
    states = table(tmp_path / "fleet", "joint_states")
    assert states.num_rows == 150 and states.column("position_0").null_count == 0
    assert states.column("velocity_0").null_count == 150


def test_an_rtraw_of_an_unknown_layout_is_refused_with_what_why_how(tmp_path: Path):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    text = (Path(__file__).parents[2] / "src/plem/middleware/interfaces/plem_msgs/msg/RtRaw.msg").read_text()
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(text + "\nfloat64 torque_scale\n", "plem_msgs/msg/RtRaw"))
    robot = tmp_path / "bags" / "arm"
    robot.mkdir(parents=True)
    SegmentWriter(robot / "arm_2027_01_16-00_00_00", [("/arm/rt_raw", "plem_msgs/msg/RtRaw")], store).close()
    result = run_plem("bag", "export", str(tmp_path / "bags"), "--to", str(tmp_path / "fleet"))
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert "ERROR: rt_raw of arm_2027_01_16-00_00_00 has a layout this plem does not know" in result.stderr
    assert "speed_override, torque_scale" in result.stderr and "HOW: export it with the plem version" in result.stderr


def test_malformed_identity_in_a_bag_reads_as_unknown(tmp_path: Path):
    """custom_data edited by hand (joint names that are not a JSON list): the names come from joint_states."""
    from plem.middleware.types import library

    robot = tmp_path / "bags" / "arm"
    robot.mkdir(parents=True)
    writer = SegmentWriter(robot / "arm_2027_01_16-00_00_00", [("/arm/joint_states", "sensor_msgs/msg/JointState")],
                           STORE, custom_data={"plem.joint_names": "[oops", "plem.serial": "PE07I7E0E001"})
    message = library().new("sensor_msgs/msg/JointState", name=joints(6), position=[0.0] * 6)
    writer.append("/arm/joint_states", MIDNIGHT, message.serialize())
    writer.close()
    report = export([tmp_path / "bags"], open_destination(str(tmp_path / "fleet")))
    assert report.problems == [] and report.exported == ["arm/arm_2027_01_16-00_00_00"]
    [row] = table(tmp_path / "fleet", "segments").to_pylist()
    assert row["joint_names"] == joints(6) and row["serial"] == "PE07I7E0E001" and row["dof"] == 6


def test_a_message_that_does_not_decode_skips_its_segment_with_what_why_how(bag_dir: Path, tmp_path: Path):
    bags = tmp_path / "bags"
    shutil.copytree(bag_dir / "arm_b", bags / "arm_b")
    broken = bags / "arm_b" / "arm_b_2027_01_17-00_00_00"
    writer = SegmentWriter(broken, [("/arm_b/rt_events", "plem_msgs/msg/RtEvent")], STORE)
    writer.append("/arm_b/rt_events", MIDNIGHT + DAY, b"\x00\x01\x00\x00\x07\x00")    # cut after 2 bytes
    writer.close()
    result = run_plem("bag", "export", str(bags), "--to", str(tmp_path / "fleet"))
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    assert f"ERROR: segment {broken.name} not exported: a message in it cannot be decoded" in result.stderr
    assert "exported 2 segments" in result.stdout
