from pathlib import Path

import pytest

from plem.errors import ConfigError, MultipleErrors
from plem.robot import MODELS, Indy7, Indy7V2, IndyRP2, SerialArmConfig, model_for
from plem.robot.config import robot_id_problem


def test_defaults_follow_the_reference():
    config = SerialArmConfig(dof=6)
    assert (config.network_interface, config.master_index, config.cycle_time, config.rt_priority) == (
        "eth0", 0, 1000, 98)
    assert config.robot_serial is None and config.robot_id == "" and config.custom_bus is None
    assert config.joint_offsets == [0] * 6
    assert config.validate() == []


def test_presets_fix_dof_and_carry_model_defaults():
    assert Indy7().dof == 6 and IndyRP2().dof == 7 and len(IndyRP2().joint_offsets) == 7
    with pytest.raises(TypeError):
        Indy7(dof=7)
    model = Indy7V2.MODEL
    assert model.joint_names == tuple(f"joint{i}" for i in range(6))
    assert model.description_package == "indy7_v2_description"
    assert len(model.encoder_counts_per_rev) == len(model.gear_ratios) == 6
    assert set(MODELS) == {"indy7", "indy7_v2", "indy12", "indy12_v2", "indyrp2", "indyrp2_v2"}
    assert all(MODELS[t].MODEL.dof == (7 if t.startswith("indyrp2") else 6) for t in MODELS)


def test_unknown_robot_type_lists_the_known_ones():
    with pytest.raises(ConfigError) as error:
        model_for("indy9")
    assert "indy7_v2" in error.value.what


def test_rt_priority_99_is_refused_with_the_reason():
    with pytest.raises(ConfigError) as error:
        Indy7(rt_priority=99).validate()
    assert error.value.summary == "rt_priority out of range"
    assert "watchdog" in error.value.why


@pytest.mark.parametrize("value", [0, 1, 98, 99, 100, -5])
def test_rt_priority_range(value):
    config = Indy7(rt_priority=value)
    assert (config.problems() == []) == (1 <= value <= 98)


@pytest.mark.parametrize("value, ok", [(249, False), (250, True), (1000, True), (2000, True), (2001, False)])
def test_cycle_time_range(value, ok):
    assert (Indy7(cycle_time=value).problems() == []) is ok


def test_fast_cycle_warns_without_rt_kernel(tmp_path: Path):
    absent, present = tmp_path / "absent", tmp_path / "realtime"
    present.write_text("1\n")
    assert "PREEMPT_RT" in Indy7(cycle_time=500).validate(rt_kernel_flag=absent)[0]
    assert Indy7(cycle_time=500).validate(rt_kernel_flag=present) == []
    assert Indy7(cycle_time=1000).validate(rt_kernel_flag=absent) == []


def test_joint_offsets_length_message():
    with pytest.raises(ConfigError) as error:
        Indy7(joint_offsets=[1, 2, 3]).validate()
    assert error.value.summary == "joint_offsets must have exactly 6 elements"


@pytest.mark.parametrize("offsets", [[0, 0, 0, 0, 0, 2**31], [0, 0, 0, 0, 0, 1.5], [0, 0, 0, 0, 0, True]])
def test_joint_offsets_must_be_int32(offsets):
    assert Indy7(joint_offsets=offsets).problems()


@pytest.mark.parametrize("robot_id, ok", [
    ("", True), ("indy", True), ("arm_left", True), ("_x1", True),
    ("1arm", False), ("arm-left", False), ("arm/left", False), ("a__b", False), ("arm left", False),
])
def test_robot_id_is_a_ros2_name_token(robot_id, ok):
    assert (robot_id_problem(robot_id) is None) is ok


@pytest.mark.parametrize("serial", ["../x", "a/b", "", ".hidden"])
def test_unsafe_robot_serial_is_refused(serial):
    assert Indy7(robot_serial=serial).problems()


@pytest.mark.parametrize("name", ["", "a" * 16, "eth 0", "eth0/1"])
def test_malformed_interface_name(name):
    assert Indy7(network_interface=name).problems()


def test_unsupported_dof():
    assert "not supported" in SerialArmConfig(dof=8).problems()[0].summary


def test_all_problems_are_reported_together():
    with pytest.raises(MultipleErrors) as error:
        Indy7(rt_priority=99, cycle_time=5, master_index=-1, robot_id="1x").validate()
    assert len(error.value.errors) == 4
