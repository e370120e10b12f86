import json
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from plem.cli import run
from tests.e2e.cli import run_plem


def test_show_prints_every_field_with_its_source():
    result = run_plem("config", "show", "robot_type:=indy7_v2", "rt_priority:=80",
                      env={"PLEM_NETWORK_INTERFACE": "enp3s0"})
    assert result.returncode == 0, result.stderr
    out = result.stdout
    for expected in ("Indy7V2", "launch argument rt_priority:=80", "environment PLEM_NETWORK_INTERFACE",
                     "model default Indy7V2", "launch default robot_id:=indy", "ros_domain_id"):
        assert expected in out


def test_show_json():
    result = run_plem("config", "show", "--rt_priority", "70", "--format", "json", "robot_type:=indyrp2")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["model"] == "IndyRP2" and data["fields"]["dof"]["value"] == 7
    assert data["fields"]["rt_priority"] == {"value": 70, "source": "launch argument rt_priority:=70"}


def test_bad_value_is_an_error_without_traceback():
    result = run_plem("config", "show", "rt_priority:=99")
    assert result.returncode == 1
    assert result.stderr.startswith("ERROR: rt_priority out of range")
    assert "WHAT:" in result.stderr and "WHY:" in result.stderr and "HOW:" in result.stderr
    assert "Traceback" not in result.stderr + result.stdout


def test_unknown_argument_is_a_usage_error():
    result = run_plem("config", "show", "rt_prio:=3")
    assert result.returncode == 2
    assert "did you mean rt_priority" in result.stderr


def test_warnings_go_to_stderr():
    result = run_plem("config", "show", "cycle_time:=500", env={"RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"})
    assert result.returncode == 0
    assert "WARNING: RMW_IMPLEMENTATION=rmw_fastrtps_cpp" in result.stderr
    rt_kernel = Path("/sys/kernel/realtime").exists()
    assert ("WARNING: cycle_time 500" in result.stderr) is not rt_kernel


def test_bad_domain_id_is_reported():
    result = run_plem("config", "show", env={"ROS_DOMAIN_ID": "abc"})
    assert result.returncode == 1 and "ROS_DOMAIN_ID" in result.stderr


words = st.one_of(
    st.sampled_from(["config", "show", "profile", "create", "list", "--format", "json", "--serial", "--offsets",
                     "rt_priority:=", "robot_type:=", "--help", "--dof", "x", "7", ":=", "--"]),
    st.text(max_size=12),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(argv=st.lists(words, max_size=6))
def test_no_command_line_produces_a_traceback(argv, capsys):
    code = run(argv)
    captured = capsys.readouterr()
    assert code in (0, 1, 2)
    assert "Traceback" not in captured.out + captured.err
    assert "Internal error" not in captured.err
