"""`plem fleet query|faults|health|usage` with DuckDB on a two-robot dataset (a 6- and a 7-axis arm) whose answers
are known by construction, the output formats, older and newer schema versions, and the WHAT/WHY/HOW errors."""

from __future__ import annotations

import csv
import io
import json
import math
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from plem.cli.app import run
from plem.fleet import schema
from plem.fleet.synthetic import AMPLITUDE, EFFORT, FOLLOWING, PERIOD_S, Fault, Run, write_run
from tests.integration.fleet_dataset import DAY_1, write_fleet

OMEGA = 2 * math.pi / PERIOD_S


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_fleet(tmp_path_factory.mktemp("fleet") / "dataset")


def plem(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = run(list(args))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def health_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, list[dict[str, object]]]:
    code, out, err = plem(capsys, "fleet", "health", *args, "--format", "json")
    assert code == 0, err
    result: dict[str, list[dict[str, object]]] = json.loads(out)
    return result


COUNT_SQL = "SELECT robot_id, count(*) AS n, count(position_6) AS seventh FROM rt_raw GROUP BY 1 ORDER BY 1"


def test_query_prints_csv_json_and_a_table(fleet: Path, capsys: pytest.CaptureFixture[str]):
    code, out, _ = plem(capsys, "fleet", "query", str(fleet), COUNT_SQL, "--format", "csv")
    # arm_a lost a second of rt_raw on its first day; only arm_b has a 7th joint
    assert code == 0 and out == "robot_id,n,seventh\narm_a,15000,0\narm_b,16000,16000\n"
    code, out, _ = plem(capsys, "fleet", "query", str(fleet), COUNT_SQL, "--format", "json")
    assert code == 0 and json.loads(out) == [{"robot_id": "arm_a", "n": 15000, "seventh": 0},
                                             {"robot_id": "arm_b", "n": 16000, "seventh": 16000}]
    code, out, _ = plem(capsys, "fleet", "query", str(fleet), COUNT_SQL)
    assert code == 0 and "┃ robot_id" in out and "│ arm_b    │ 16000 │ 16000" in out
    code, out, _ = plem(capsys, "fleet", "query", str(fleet), "SELECT * FROM rt_raw WHERE false")
    assert code == 0 and out.strip() == "The query returned no rows."


def test_every_table_is_a_view_with_robot_and_date(fleet: Path, capsys: pytest.CaptureFixture[str]):
    sql = ("SELECT 'rt_events', count(*), min(date) FROM rt_events UNION ALL SELECT 'rt_monitor_stats', count(*), "
           "min(date) FROM rt_monitor_stats UNION ALL SELECT 'joint_states', count(*), min(date) FROM joint_states "
           "UNION ALL SELECT 'segments', count(*), min(date) FROM segments")
    code, out, _ = plem(capsys, "fleet", "query", str(fleet), sql, "--format", "csv")
    rows = list(csv.reader(io.StringIO(out)))[1:]
    # events: a mode change in and out of every run plus two faults; 10 Hz statistics; 100 Hz joint states;
    # one segment per 4 s
    assert code == 0 and rows == [["rt_events", "10", "2026-11-02"], ["rt_monitor_stats", "320", "2026-11-02"],
                                  ["joint_states", "3200", "2026-11-02"], ["segments", "8", "2026-11-02"]]


def test_health_per_robot_per_day_and_the_trend(fleet: Path, capsys: pytest.CaptureFixture[str]):
    report = health_json(capsys, str(fleet))
    # latency percentiles of the synthetic pattern over whole seconds: base + 49, + 98, + 99 µs; max base + 99.9
    expected = [
        {"robot_id": "arm_a", "day": "2026-11-02", "cycles": 7000, "overruns": 3, "missed_periods": 1,
         "lost_frames": 2, "latency_p50_us": 59, "latency_p99_us": 108, "latency_p999_us": 109,
         "latency_max_us": 109.9},
        {"robot_id": "arm_a", "day": "2026-11-03", "cycles": 8000, "overruns": 5, "missed_periods": 1,
         "lost_frames": 0, "latency_p50_us": 59, "latency_p99_us": 108, "latency_p999_us": 109,
         "latency_max_us": 109.9},
        {"robot_id": "arm_b", "day": "2026-11-02", "cycles": 8000, "overruns": 0, "missed_periods": 0,
         "lost_frames": 0, "latency_p50_us": 69, "latency_p99_us": 118, "latency_p999_us": 119,
         "latency_max_us": 119.9},
        {"robot_id": "arm_b", "day": "2026-11-03", "cycles": 8000, "overruns": 0, "missed_periods": 0,
         "lost_frames": 0, "latency_p50_us": 79, "latency_p99_us": 128, "latency_p999_us": 129,
         "latency_max_us": 129.9},
    ]
    assert report["days"] == expected
    trend = {row["robot_id"]: row for row in report["trend"]}
    assert trend["arm_a"]["overruns_per_week"] == pytest.approx(14) and trend["arm_a"]["grows"] == "overruns"
    assert trend["arm_a"]["lost_frames_per_week"] == pytest.approx(-14)
    assert trend["arm_b"]["latency_p99_us_per_week"] == pytest.approx(70)
    assert trend["arm_b"]["grows"] == "latency_p99_us"
    code, out, _ = plem(capsys, "fleet", "health", str(fleet))
    assert code == 0 and "Growing week on week: arm_a (overruns); arm_b (latency_p99_us)" in out


def test_health_since_a_date_and_an_empty_range(fleet: Path, capsys: pytest.CaptureFixture[str]):
    report = health_json(capsys, str(fleet), "--since", "2026-11-03")
    assert [(row["robot_id"], row["day"], row["overruns"]) for row in report["days"]] == \
        [("arm_a", "2026-11-03", 5), ("arm_b", "2026-11-03", 0)]
    code, out, err = plem(capsys, "fleet", "health", str(fleet), "--since", "2027-01-01")
    assert code == 0 and err == ""
    assert out.strip() == f"No rt_raw or rt_monitor_stats rows in {fleet} since 2027-01-01T00:00:00+00:00."


def test_faults_with_the_second_before_each(fleet: Path, capsys: pytest.CaptureFixture[str]):
    code, out, err = plem(capsys, "fleet", "faults", str(fleet), "--format", "json")
    assert code == 0, err
    first, second = json.loads(out)
    assert (first["robot_id"], first["time"], first["cause"], first["mode"], first["previous_mode"]) == \
        ("arm_a", "2026-11-02T08:00:02.500000+00:00", "tracking_error", "fault", "position")
    assert first["reason"].startswith("joint 1 followed its command")
    # the second before 2.5 s lost its last half (rt_raw 2.0–3.0 s missing)
    assert (first["cycles"], first["expected"], first["lost"]) == (500, 1000, 500)
    assert first["peak_velocity"] == pytest.approx(AMPLITUDE[5] * OMEGA, rel=1e-5)
    assert first["velocity_joint"] == "joint6" and first["following_joint"] == "joint6"
    assert first["peak_following_error"] == pytest.approx(FOLLOWING[5])
    assert first["peak_effort"] == pytest.approx(EFFORT[5], rel=1e-5) and first["effort_joint"] == "joint6"
    assert first["compute_max_us"] == 5.9 and first["latency_max_us"] <= 109.9
    # the 7-axis arm: its 7th joint moves most
    assert (second["robot_id"], second["cause"], second["cycles"], second["lost"]) == ("arm_b", "joint_limit", 1000, 0)
    assert second["velocity_joint"] == "joint7" and second["peak_following_error"] == pytest.approx(FOLLOWING[6])
    # a whole second of the latency pattern (base 30 µs)
    assert (second["latency_p99_us"], second["latency_max_us"], second["compute_max_us"]) == (128, 129.9, 5.9)
    code, out, _ = plem(capsys, "fleet", "faults", str(fleet), "--since", "2026-11-03", "--format", "csv")
    assert code == 0 and [row[0] for row in csv.reader(io.StringIO(out))] == ["robot_id", "arm_b"]
    code, out, _ = plem(capsys, "fleet", "faults", str(fleet), "--since", "2027-01-01")
    assert code == 0 and out.strip() == f"No faults in {fleet} since 2027-01-01T00:00:00+00:00."
    code, out, _ = plem(capsys, "fleet", "faults", str(fleet))
    assert code == 0 and "Faults per robot: arm_a 1, arm_b 1" in out


def test_usage_sorted_by_travel(fleet: Path, capsys: pytest.CaptureFixture[str]):
    code, out, err = plem(capsys, "fleet", "usage", str(fleet), "--format", "json")
    assert code == 0, err
    rows = json.loads(out)
    assert len(rows) == 13   # 6 + 7 joints
    assert [row["travel"] for row in rows] == sorted((row["travel"] for row in rows), reverse=True)
    top = rows[0]
    # 16 s of a 4 s sine: 4 periods of 4 · amplitude, 2 reversals a period, RMS effort amplitude / √2
    assert (top["robot_id"], top["joint"], top["joint_name"]) == ("arm_b", 6, "joint7")
    assert top["travel"] == pytest.approx(16 * AMPLITUDE[6], rel=1e-3)
    assert top["reversals"] == 8 and top["samples"] == 16000
    assert top["rms_effort"] == pytest.approx(EFFORT[6] / math.sqrt(2), rel=1e-9)
    arm_a_first = next(row for row in rows if row["robot_id"] == "arm_a" and row["joint"] == 0)
    assert arm_a_first["travel"] == pytest.approx(16 * AMPLITUDE[0], rel=1e-3) and arm_a_first["reversals"] == 8


def test_plots_are_written(fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    for command in ("health", "usage"):
        picture = tmp_path / f"{command}.png"
        code, _, err = plem(capsys, "fleet", command, str(fleet), "--plot", str(picture))
        assert code == 0, err
        assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and picture.stat().st_size > 20_000


def test_older_schema_files_read_with_nulls(fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    dataset = tmp_path / "dataset"
    shutil.copytree(fleet, dataset)
    old = write_run(tmp_path / "old", Run("arm_c", 6, DAY_1, 2, segment_seconds=2))
    for path in old:   # an older plem: no speed_override in rt_raw, no version recorded
        table = pq.read_table(path)
        if "speed_override" in table.column_names:
            table = table.drop_columns(["speed_override"])
        table = table.replace_schema_metadata({})
        target = dataset / path.relative_to(tmp_path / "old")
        target.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table, target)
    code, out, err = plem(capsys, "fleet", "query", str(dataset), "SELECT robot_id, count(*), count(speed_override) "
                          "FROM rt_raw GROUP BY 1 ORDER BY 1", "--format", "csv")
    assert code == 0, err
    assert out == "robot_id,count_star(),count(speed_override)\narm_a,15000,15000\narm_b,16000,16000\narm_c,2000,0\n"
    report = health_json(capsys, str(dataset))
    assert ("arm_c", "2026-11-02", 2000) in [(row["robot_id"], row["day"], row["cycles"]) for row in report["days"]]


def test_a_newer_schema_is_refused_and_left_as_it_is(fleet: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]):
    dataset = tmp_path / "dataset"
    shutil.copytree(fleet, dataset)
    newer = sorted((dataset / "rt_raw").rglob("*.parquet"))[0]
    table = pq.read_table(newer)
    pq.write_table(table.replace_schema_metadata({schema.VERSION_KEY: str(schema.SCHEMA_VERSION + 1).encode()}),
                   newer)
    before = newer.read_bytes()
    code, _, err = plem(capsys, "fleet", "health", str(dataset))
    assert code == 1 and err.startswith("ERROR: The dataset holds files of a newer schema")
    assert f"version {schema.SCHEMA_VERSION + 1}" in err and str(newer) in err and "HOW: upgrade plem" in err
    assert newer.read_bytes() == before


@pytest.mark.parametrize(("dest", "message"), [
    ("missing", "ERROR: No fleet dataset at {dest}\nWHAT: DEST: the directory"),
    ("empty", "ERROR: {dest} is not a fleet dataset"),
])
def test_a_wrong_dest_is_what_why_how(dest: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    path = tmp_path / dest
    if dest == "empty":
        (path / "rt_raw").mkdir(parents=True)
        (path / "rt_raw" / "half.parquet.tmp").write_bytes(b"PAR1")   # an export's temporary file is not data
    code, _, err = plem(capsys, "fleet", "query", str(path), "SELECT 1")
    assert code == 1 and err.startswith(message.format(dest=path)) and "HOW: " in err and "Traceback" not in err


def test_a_failing_query_names_the_tables(fleet: Path, capsys: pytest.CaptureFixture[str]):
    code, _, err = plem(capsys, "fleet", "query", str(fleet), "SELECT latency FROM rt_raw")
    assert code == 1 and err.startswith("ERROR: The query failed")
    assert 'WHY: DuckDB: Binder Error: Referenced column "latency" not found' in err
    assert f'HOW: the tables are rt_raw, rt_events, rt_monitor_stats, joint_states, segments; list a table\'s ' \
           f'columns with `plem fleet query {fleet} "DESCRIBE rt_raw"`' in err


def test_a_wrong_since_is_what_why_how(fleet: Path, capsys: pytest.CaptureFixture[str]):
    code, _, err = plem(capsys, "fleet", "faults", str(fleet), "--since", "yesterday")
    assert code == 1 and err.startswith("ERROR: --since 'yesterday' is not a date or a duration")
    assert "HOW: pass e.g. --since 7d" in err


def test_a_scheduler_without_the_dask_engine_is_a_usage_error(fleet: Path, capsys: pytest.CaptureFixture[str]):
    code, _, err = plem(capsys, "fleet", "health", str(fleet), "--scheduler", "tcp://127.0.0.1:8786")
    assert code == 2 and err.startswith("ERROR: --scheduler needs --engine dask")
    assert "HOW: add --engine dask, or leave --scheduler out" in err


def test_a_damaged_file_is_named_with_how_to_export_it_again(fleet: Path, tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]):
    dataset = tmp_path / "dataset"
    shutil.copytree(fleet, dataset)
    damaged = sorted((dataset / "rt_raw").rglob("*.parquet"))[0]
    damaged.write_bytes(damaged.read_bytes()[:5000])   # cut short, as a copy interrupted by hand leaves it
    code, _, err = plem(capsys, "fleet", "health", str(dataset))
    assert code == 1 and err.startswith("ERROR: A file of the dataset cannot be read")
    assert f"WHY: {damaged}: DuckDB: " in err
    assert f"HOW: move {damaged} out of {dataset} (the rest is read without it); to export its segment again, " \
           f"move {dataset}/segments/robot_id=arm_a/date=*/{damaged.name} out too" in err
    assert len(damaged.read_bytes()) == 5000   # left as it was


def test_a_fault_soon_after_start_expects_only_the_cycles_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    write_run(tmp_path, Run("arm_s", 6, DAY_1, 2, segment_seconds=2, faults=(Fault(0.3),)))
    code, out, err = plem(capsys, "fleet", "faults", str(tmp_path), "--format", "json")
    assert code == 0, err
    [fault] = json.loads(out)
    # 0.3 s after the loop started: 300 cycles ran (0 … 299), none lost
    assert (fault["cycle"], fault["cycles"], fault["expected"], fault["lost"]) == (300, 300, 300, 0)
