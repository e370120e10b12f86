"""controllers.yaml as plem runs it: names, joints and interfaces of the controllers, in either ros2_control style."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.description.controllers import controllers_from, read_controllers
from plem.description.generate import controllers_yaml
from plem.errors import ConfigError

JOINTS = tuple(f"joint{i}" for i in range(6))
BUILTIN = sorted(path.name for path in BUILTIN_PACKAGES_DIR.glob("*_description"))
#: The configuration reference's example: types under controller_manager, joints under each controller.
SPEC_EXAMPLE = """
controller_manager:
  ros__parameters:
    update_rate: 500
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    joint_trajectory_controller:
      type: joint_trajectory_controller/JointTrajectoryController
    free_drive_controller:
      type: wim_controller/FreeDriveController
joint_trajectory_controller:
  ros__parameters:
    joints: [joint0, joint1, joint2, joint3, joint4, joint5]
    command_interfaces: [position, velocity, acceleration]
    state_interfaces: [position, velocity]
"""


def test_the_generated_file_names_the_arm_controller_the_broadcaster_and_free_drive():
    controllers = read_controllers(None, JOINTS, cycle_time_us=1000)
    assert controllers.update_rate == 1000.0
    assert controllers.trajectory.name == "arm_controller"
    assert controllers.trajectory.joints == JOINTS and controllers.trajectory.command_interfaces == ("position",)
    broadcaster, free_drive = controllers.by_role("broadcaster"), controllers.by_role("free_drive")
    assert broadcaster is not None and broadcaster.name == "joint_state_broadcaster"
    assert free_drive is not None and free_drive.name == "free_drive_controller"
    assert controllers.trajectory.claimed()[:2] == ("joint0/position", "joint1/position")


def test_the_configuration_references_example_keeps_its_names_and_interfaces(tmp_path: Path):
    path = tmp_path / "controllers.yaml"
    path.write_text(SPEC_EXAMPLE)
    controllers = read_controllers(path, JOINTS, cycle_time_us=1000)
    assert controllers.update_rate == 500.0
    assert [c.name for c in controllers.controllers] == ["joint_state_broadcaster", "joint_trajectory_controller",
                                                         "free_drive_controller"]
    assert controllers.trajectory.command_interfaces == ("position", "velocity", "acceleration")
    assert not controllers.unsupported


def test_a_file_without_a_trajectory_controller_gets_the_default_one_and_lists_other_types_as_unsupported():
    document = {"controller_manager": {"ros__parameters": {"gripper": {"type": "gripper_controllers/Gripper"}}}}
    controllers = controllers_from(document, JOINTS, "controllers.yaml")
    assert controllers.trajectory.name == "joint_trajectory_controller"
    assert [c.name for c in controllers.unsupported] == ["gripper"]
    assert controllers.update_rate is None


@pytest.mark.parametrize(("document", "words"), [
    ({"a": {"ros__parameters": {"type": "joint_trajectory_controller/JointTrajectoryController"}},
      "b": {"ros__parameters": {"type": "joint_trajectory_controller/JointTrajectoryController"}}},
     "declares 2 trajectory controllers"),
    ({"arm": {"ros__parameters": {"type": "joint_trajectory_controller/JointTrajectoryController",
                                  "joints": ["joint0", "joint1"]}}}, "does not cover the arm"),
])
def test_trajectory_controllers_plem_cannot_run_are_explained(document, words):
    with pytest.raises(ConfigError) as refused:
        controllers_from(document, JOINTS, "controllers.yaml")
    assert words in refused.value.summary and refused.value.how


def test_the_generated_text_reads_back_as_yaml_with_its_types_under_the_controller_manager():
    data = yaml.safe_load(controllers_yaml(list(JOINTS)))
    assert set(data["controller_manager"]["ros__parameters"]) == {"update_rate", "joint_state_broadcaster",
                                                                  "arm_controller", "free_drive_controller"}


@pytest.mark.parametrize("package", BUILTIN)
def test_every_built_in_arm_runs_the_configuration_references_controllers(package: str):
    """joint_state_broadcaster, joint_trajectory_controller (position, velocity, acceleration) and
    free_drive_controller over joint0..jointN at 500 Hz, as the configuration reference's controllers.yaml gives."""
    path = BUILTIN_PACKAGES_DIR / package / "config" / "controllers.yaml"
    joints = tuple(yaml.safe_load((path.parent / "joint_limits.yaml").read_text())["joint_limits"])
    assert joints == tuple(f"joint{i}" for i in range(len(joints))) and len(joints) in (6, 7)
    controllers = read_controllers(path, joints, cycle_time_us=1000)
    assert controllers.update_rate == 500.0
    assert {c.name: c.type for c in controllers.controllers} == {
        "joint_state_broadcaster": "joint_state_broadcaster/JointStateBroadcaster",
        "joint_trajectory_controller": "joint_trajectory_controller/JointTrajectoryController",
        "free_drive_controller": "wim_controller/FreeDriveController"}
    trajectory = controllers.trajectory
    assert trajectory.name == "joint_trajectory_controller" and trajectory.joints == joints
    assert trajectory.command_interfaces == ("position", "velocity", "acceleration")
    assert trajectory.state_interfaces == ("position", "velocity")
    assert controllers.named("joint_state_broadcaster").joints == joints


def test_the_reported_rate_is_the_files_at_most_the_loops_and_the_loops_without_one():
    spec = controllers_from(yaml.safe_load(SPEC_EXAMPLE), JOINTS, "controllers.yaml")
    assert spec.rate(0.001) == 500 and spec.rate_warning(0.001) is None
    assert spec.rate(0.002) == 500 and spec.rate_warning(0.002) is None    # the loop's own rate is allowed
    assert controllers_from({}, JOINTS, "controllers.yaml").rate(0.00025) == 4000


def test_an_update_rate_above_the_loops_is_reported_as_the_loops_with_a_warning_naming_both_fixes():
    document = {"controller_manager": {"ros__parameters": {"update_rate": 2000}}}
    controllers = controllers_from(document, JOINTS, "pkg/config/controllers.yaml")
    assert controllers.rate(0.001) == 1000
    warning = controllers.rate_warning(0.001)
    assert warning is not None
    assert "2000 Hz" in warning.summary and "1000 Hz" in warning.summary
    assert "pkg/config/controllers.yaml" in warning.why and "1000 µs" in warning.why
    assert "update_rate: 1000" in warning.how and "cycle_time:=500" in warning.how
    beyond = controllers_from({"controller_manager": {"ros__parameters": {"update_rate": 8000}}}, JOINTS, "c.yaml")
    assert "cycle_time:=" not in beyond.rate_warning(0.001).how     # no cycle_time reaches 8 kHz (250 µs at least)
