"""Missing meshes at launch: a missing collision mesh disables the robot's planner, and the rest of the launch runs."""

from __future__ import annotations

from pathlib import Path

from tests.e2e.launched import clean_environment, launched, new_robot_id
from tests.integration.packages import copy_builtin

BASE_LINK = '<link name="${pfx}link0">  <!-- base -->'
#: The base link gains a collision mesh and a visual mesh, neither of which exists.
MISSING_MESHES = (BASE_LINK + "\n"
                  '    <visual><geometry><mesh filename="package://indy7_v2_description/meshes/base.dae"/></geometry>'
                  "</visual>\n"
                  '    <collision><geometry><mesh filename="package://indy7_v2_description/meshes/base.stl"/>'
                  "</geometry></collision>")


def test_missing_collision_mesh_disables_planning_and_the_arm_runs(tmp_path: Path):
    package = copy_builtin("indy7_v2", tmp_path / "packages")
    urdf = package / "urdf" / "indy7_v2.urdf.xacro"
    urdf.write_text(urdf.read_text().replace(BASE_LINK, MISSING_MESHES))
    robot_id = new_robot_id()
    arguments = ["bus:=mock", f"robot_id:={robot_id}", f"description_package:={package}", "planner:=true",
                 "record:=false", "bridge:=false"]
    with launched(arguments, [robot_id], tmp_path, clean_environment(tmp_path / "home")) as launch:
        output = launch.output
        assert launch.driver_pids().keys() == {robot_id}, launch.describe()
        assert "planner       not started: Planning is disabled: 1 collision mesh not found" in output, \
            launch.describe()
        warning = output[output.index(f"[{robot_id}] warning: Planning is disabled"):]
        assert "WHY: link link0: " in warning and "meshes/base.stl" in warning and "HOW: add the files" in warning
        assert "base.dae" not in output  # a missing visual mesh does not concern the launch
        assert launch.process.poll() is None
