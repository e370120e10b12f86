"""A recorded session of two robots (a 6- and a 7-axis arm, bags written by the recorder's own code), exported with
`plem bag export` and queried with `plem fleet`: the faults found with their cause and the second before them, the
health report by DuckDB equal to Dask's on a local cluster of 2 workers, and every exported row counted."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from distributed import Client, LocalCluster

from plem.cli.app import run
from plem.fleet import dask_engine, health
from plem.fleet.dataset import open_dataset
from tests.e2e.cli import run_plem
from tests.integration.fleet_bags import MS, S, record_robot

START = 1_800_057_600 * S + 8 * 3_600 * S     # 2027-01-16T08:00:00Z
ROBOTS = {"arm_a": dict(start_ns=START, cycles=2500, dof=6, seed=1),
          "arm_b": dict(start_ns=START + 10 * S, cycles=2000, dof=7, seed=2, lost_after=1500)}


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    bags = tmp_path_factory.mktemp("bags")
    for robot_id, options in ROBOTS.items():
        record_robot(bags / robot_id, **options)
    destination = tmp_path_factory.mktemp("fleet") / "dataset"
    result = run_plem("bag", "export", str(bags), "--to", str(destination))
    assert result.returncode == 0, result.stderr
    return destination


def test_the_exported_session_is_queried(exported: Path, capsys: pytest.CaptureFixture[str]):
    assert run(["fleet", "query", str(exported), "SELECT robot_id, count(*) AS n, count(position_6) AS seventh, "
                "max(dof) AS dof FROM rt_raw JOIN (SELECT DISTINCT robot_id, dof FROM segments) USING (robot_id) "
                "GROUP BY 1 ORDER BY 1", "--format", "json"]) == 0
    # arm_b lost 3 cycles after cycle 1500 of its 2000
    assert json.loads(capsys.readouterr().out) == [{"robot_id": "arm_a", "n": 2500, "seventh": 0, "dof": 6},
                                                   {"robot_id": "arm_b", "n": 2000, "seventh": 2000, "dof": 7}]


def test_the_faults_of_the_recorded_session(exported: Path, capsys: pytest.CaptureFixture[str]):
    assert run(["fleet", "faults", str(exported), "--format", "json"]) == 0
    faults = json.loads(capsys.readouterr().out)
    assert [(fault["robot_id"], fault["cause"], fault["cycle"]) for fault in faults] == \
        [("arm_a", "drive_fault", 1200), ("arm_b", "drive_fault", 1200)]
    for fault, start_ns in zip(faults, (ROBOTS["arm_a"]["start_ns"], ROBOTS["arm_b"]["start_ns"]), strict=True):
        assert pd.Timestamp(fault["time"]).value == start_ns + 1200 * MS
        assert fault["reason"] == "joint2: drive fault 0x7121 (following error)"
        # the second before cycle 1200: cycles 200 … 1199, all recorded, at the 1 ms period of the statistics
        assert (fault["cycles"], fault["expected"], fault["lost"]) == (1000, 1000, 0)
        assert fault["peak_velocity"] > 0 and fault["velocity_joint"].startswith("joint")


def test_health_of_the_recorded_session_by_duckdb_and_dask(exported: Path):
    dataset = open_dataset(str(exported))
    by_duckdb = health.days(*health.duckdb_aggregates(dataset, None))
    assert by_duckdb[["robot_id", "cycles"]].values.tolist() == [["arm_a", 2500], ["arm_b", 2000]]
    _, rows = dataset.rows("SELECT robot_id, max(overruns) FROM rt_monitor_stats GROUP BY 1 ORDER BY 1")
    assert by_duckdb["overruns"].tolist() == [row[1] for row in rows]   # one run each: the counter's last value
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            Client(cluster) as client:
        by_dask = health.days(*dask_engine.aggregates(dataset, None, client))
    pd.testing.assert_frame_equal(by_dask, by_duckdb, check_exact=True)
