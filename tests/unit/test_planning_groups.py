"""Planning groups from the SRDF and kinematics.yaml: joints, IK link, solver settings and their problems."""

from __future__ import annotations

from pathlib import Path

import pytest

from plem.description.model import parse_srdf
from plem.description.validate import validate_package
from plem.errors import ConfigError
from plem.planning.groups import SOLVER, read_groups

REPORT = validate_package("indy7_v2_description")
JOINTS = tuple(f"joint{i}" for i in range(6))
SRDF = """<robot name="indy7">
  <group name="arm"><chain base_link="link0" tip_link="tcp"/></group>
  <group name="wrist"><joint name="joint3"/><joint name="joint4"/><joint name="joint5"/></group>
  <group name="shoulder"><link name="link1"/><link name="link2"/></group>
  <group name="both"><group name="shoulder"/><group name="wrist"/></group>
  <group name="base"><link name="link0"/></group>
</robot>"""


def groups(tmp_path: Path, kinematics: str | None) -> tuple[dict, list[str]]:
    path = None
    if kinematics is not None:
        path = tmp_path / "kinematics.yaml"
        path.write_text(kinematics)
    assert REPORT.urdf is not None
    return read_groups(parse_srdf(SRDF, Path("indy7.srdf")), REPORT.urdf, JOINTS, path)


def test_chains_joint_lists_links_and_subgroups_resolve_to_the_arms_joints(tmp_path: Path) -> None:
    found, warnings = groups(tmp_path, None)
    assert found["arm"].joints == JOINTS and (found["arm"].base_link, found["arm"].tip_link) == ("link0", "tcp")
    assert found["wrist"].joints == ("joint3", "joint4", "joint5") and found["wrist"].tip_link == "tcp"
    assert found["shoulder"].joints == ("joint0", "joint1")
    assert found["both"].joints == ("joint0", "joint1", "joint3", "joint4", "joint5")
    assert "base" not in found and any("'base' moves none of the arm's joints" in w for w in warnings)


def test_kinematics_yaml_sets_timeout_and_attempts_and_names_unknown_solvers(tmp_path: Path) -> None:
    found, warnings = groups(tmp_path, "arm:\n  kinematics_solver: trac_ik_kinematics_plugin/TRAC_IKKinematicsPlugin\n"
                                       "  kinematics_solver_timeout: 0.01\n  kinematics_solver_attempts: 3\n"
                                       "wrist:\n  kinematics_solver: my_ik/MyPlugin\n"
                                       "legs:\n  kinematics_solver_timeout: 0.1\n")
    arm = found["arm"].settings
    assert arm.solver.startswith("trac_ik") and arm.timeout_s == 0.01 and arm.budget_s == pytest.approx(0.03)
    assert found["wrist"].settings.timeout_s == 0.05 and found["wrist"].settings.attempts is None
    assert any("'my_ik/MyPlugin'" in w and SOLVER in w for w in warnings)
    assert any("'legs'" in w and "not a planning group" in w for w in warnings)


@pytest.mark.parametrize("value", ["0", "-1", "nan", "fast", "true"])
def test_a_timeout_that_is_not_a_positive_number_is_refused_with_its_line(tmp_path: Path, value: str) -> None:
    with pytest.raises(ConfigError) as caught:
        groups(tmp_path, f"arm:\n  kinematics_solver_timeout: {value}\n")
    assert "kinematics_solver_timeout" in caught.value.summary and "kinematics.yaml:1" in caught.value.why
