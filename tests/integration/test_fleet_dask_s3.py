"""The health report as a Dask job on a local cluster of 2 worker processes equals DuckDB's row for row; the dataset
on a real S3-compatible server (moto's server mode) is queried like a directory; missing credentials and an
unreachable scheduler are WHAT/WHY/HOW errors."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd
import pytest
from distributed import Client, LocalCluster

from plem.cli.app import run
from plem.fleet import dask_engine, health
from plem.fleet.dataset import open_dataset
from plem.fleet.synthetic import Run, write_runs
from tests.e2e.cli import plem_executable
from tests.integration.fleet_dataset import write_fleet
from tests.local_servers import free_port, moto_server


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The two robots, a third whose counters restart twice within one day (three runs), and a fourth recording
    across midnight."""
    directory = write_fleet(tmp_path_factory.mktemp("fleet") / "dataset")
    restarts = [Run("arm_c", 6, datetime(2026, 11, 4, hour, tzinfo=UTC), 3, segment_seconds=3, overruns=hour,
                    lost_frames=2 * hour, latency_base_us=hour) for hour in (8, 9, 10)]
    across_midnight = Run("arm_d", 6, datetime(2026, 11, 4, 23, 59, 58, tzinfo=UTC), 4, segment_seconds=4,
                          overruns=4)
    write_runs(directory, [*restarts, across_midnight])
    return directory


@pytest.fixture(scope="module")
def client() -> Iterator[Client]:
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            Client(cluster) as connected:
        yield connected


@pytest.mark.parametrize("since", [None, datetime(2026, 11, 3, tzinfo=UTC)])
def test_the_dask_job_equals_duckdb_row_for_row(fleet: Path, client: Client, since: datetime | None):
    dataset = open_dataset(str(fleet))
    assert len(client.scheduler_info()["workers"]) == 2
    by_duckdb = health.days(*health.duckdb_aggregates(dataset, since))
    by_dask = health.days(*dask_engine.aggregates(dataset, since, client))
    pd.testing.assert_frame_equal(by_dask, by_duckdb, check_exact=True)
    expected_rows = 7 if since is None else 5
    assert len(by_duckdb) == expected_rows
    arm_c = by_duckdb[by_duckdb["robot_id"] == "arm_c"].iloc[0]
    # three runs in a day, each counter from 0: 8 + 9 + 10 overruns; latency bases 8, 9, 10 µs → p99.9 10 + 99
    assert (arm_c["overruns"], arm_c["lost_frames"], arm_c["latency_p999_us"]) == (27, 54, 109)
    arm_d = by_duckdb[by_duckdb["robot_id"] == "arm_d"]
    assert [(str(day), cycles) for day, cycles in zip(arm_d["day"], arm_d["cycles"], strict=True)] == \
        [("2026-11-04", 2000), ("2026-11-05", 2000)]
    assert arm_d["overruns"].sum() == 4
    pd.testing.assert_frame_equal(health.trend(by_dask), health.trend(by_duckdb), check_exact=True)


def test_the_cli_runs_the_dask_job_on_a_scheduler(fleet: Path, client: Client, capsys: pytest.CaptureFixture[str]):
    address = client.scheduler.address
    assert run(["fleet", "health", str(fleet), "--format", "csv"]) == 0
    by_duckdb = capsys.readouterr().out
    assert run(["fleet", "health", str(fleet), "--engine", "dask", "--scheduler", address, "--format", "csv"]) == 0
    assert capsys.readouterr().out == by_duckdb and by_duckdb.count("\n") == 8


def test_an_unreachable_scheduler_is_what_why_how(fleet: Path, capsys: pytest.CaptureFixture[str]):
    port = free_port()
    assert run(["fleet", "health", str(fleet), "--engine", "dask", "--scheduler", f"tcp://127.0.0.1:{port}"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"ERROR: Cannot reach the Dask scheduler at tcp://127.0.0.1:{port}")
    assert "HOW: start it (`dask scheduler`" in err


@pytest.fixture(scope="module")
def s3(fleet: Path) -> Iterator[dict[str, str]]:
    """A moto S3 server holding the dataset under s3://fleet/plant; yields its AWS_* environment."""
    import s3fs

    with moto_server() as environment:
        saved = {name: os.environ.get(name) for name in environment}
        os.environ.update(environment)
        try:
            store = s3fs.S3FileSystem(skip_instance_cache=True)
            store.mkdir("fleet")
            store.put(f"{fleet}/", "fleet/plant/", recursive=True)
            yield environment
        finally:
            for name, value in saved.items():
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value


def test_a_dataset_on_s3_is_queried_like_a_directory(fleet: Path, s3: dict[str, str],
                                                     capsys: pytest.CaptureFixture[str]):
    sql = "SELECT robot_id, count(*) AS n, count(DISTINCT date) AS days FROM rt_raw GROUP BY 1 ORDER BY 1"
    assert run(["fleet", "query", "s3://fleet/plant", sql, "--format", "csv"]) == 0
    assert capsys.readouterr().out == "robot_id,n,days\narm_a,15000,2\narm_b,16000,2\narm_c,9000,1\narm_d,4000,2\n"
    assert run(["fleet", "health", "s3://fleet/plant", "--format", "csv"]) == 0
    on_s3 = capsys.readouterr().out
    assert run(["fleet", "health", str(fleet), "--format", "csv"]) == 0
    assert on_s3 == capsys.readouterr().out


def test_missing_s3_credentials_are_what_why_how(s3: dict[str, str], tmp_path: Path):
    environment = {name: value for name, value in os.environ.items() if not name.startswith("AWS_")}
    environment.update(AWS_ENDPOINT_URL=s3["AWS_ENDPOINT_URL"], HOME=str(tmp_path),   # no ~/.aws either
                       AWS_EC2_METADATA_DISABLED="true")
    result = subprocess.run([plem_executable(), "fleet", "query", "s3://fleet/plant", "SELECT 1"],
                            capture_output=True, text=True, env=environment, timeout=60, check=False)
    assert result.returncode == 1 and result.stderr.startswith("ERROR: Cannot read s3://fleet/plant")
    assert "no credentials were found" in result.stderr and "HOW: set AWS_ACCESS_KEY_ID" in result.stderr
    assert "Traceback" not in result.stderr


def test_the_dask_job_reads_the_dataset_on_s3(fleet: Path, s3: dict[str, str]):
    local = open_dataset(str(fleet))
    by_duckdb = health.days(*health.duckdb_aggregates(local, None))
    # workers started now inherit the AWS_* variables, as a real cluster's workers need them
    with dask_engine.connect(None) as s3_client:
        by_dask = health.days(*dask_engine.aggregates(open_dataset("s3://fleet/plant"), None, s3_client))
    pd.testing.assert_frame_equal(by_dask, by_duckdb, check_exact=True)
