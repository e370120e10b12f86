from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plem.core.config.layers import LayerKind
from plem.errors import ConfigError, MultipleErrors, ProfileError
from plem.robot import Indy7V2, IndyRP2, RobotProfile, SerialArmConfig, resolve_arm_config


def test_model_defaults_when_nothing_is_set():
    resolved = resolve_arm_config("indy7_v2", environ={})
    assert isinstance(resolved.config, Indy7V2)
    assert resolved.sources["rt_priority"].detail == "model default Indy7V2"
    assert resolved.config.robot_id == ""


def test_robot_type_from_launch_argument_and_launch_defaults():
    resolved = resolve_arm_config(launch_args={"robot_type": "indyrp2"}, environ={},
                                  launch_defaults={"robot_id": "indy"})
    assert isinstance(resolved.config, IndyRP2) and resolved.config.dof == 7
    assert resolved.config.robot_id == "indy"
    assert resolved.sources["robot_id"].kind is LayerKind.LAUNCH_DEFAULT


def test_each_layer_names_its_source():
    resolved = resolve_arm_config(
        "indy7_v2",
        environ={"PLEM_RT_PRIORITY": "70", "PLEM_NETWORK_INTERFACE": "enp3s0", "PLEM_ROBOT_ID": "env_arm"},
        launch_args={"rt_priority": "80", "eth_interface": "enp2s0"},
        programmatic={"rt_priority": 50},
        launch_defaults={"robot_id": "indy"},
    )
    config, sources = resolved.config, resolved.sources
    assert config.rt_priority == 50 and str(sources["rt_priority"]) == "programmatic (set in code)"
    assert config.network_interface == "enp2s0"
    assert str(sources["network_interface"]) == "launch argument eth_interface:=enp2s0"
    assert config.robot_id == "env_arm" and str(sources["robot_id"]) == "environment PLEM_ROBOT_ID"
    assert str(sources["cycle_time"]) == "model default Indy7V2"


def test_config_object_counts_as_programmatic_for_changed_fields():
    resolved = resolve_arm_config(programmatic=Indy7V2(rt_priority=60), environ={"PLEM_RT_PRIORITY": "70",
                                                                                  "PLEM_MASTER_INDEX": "2"})
    assert resolved.config.rt_priority == 60 and resolved.config.master_index == 2
    assert resolved.sources["master_index"].detail == "environment PLEM_MASTER_INDEX"


def test_custom_arm_by_dof():
    resolved = resolve_arm_config(dof=7, environ={})
    assert type(resolved.config) is SerialArmConfig and resolved.config.dof == 7
    assert resolved.sources["dof"].detail == "model default SerialArmConfig"


def test_unknown_programmatic_field_is_an_error():
    with pytest.raises(ConfigError, match="Unknown configuration field"):
        resolve_arm_config("indy7", programmatic={"rt_prio": 3}, environ={})


def test_malformed_environment_names_the_variable_and_all_problems_come_together():
    with pytest.raises(MultipleErrors) as error:
        resolve_arm_config("indy7", environ={"PLEM_RT_PRIORITY": "abc", "PLEM_CYCLE_TIME_US": "5"})
    rendered = error.value.render()
    assert "PLEM_RT_PRIORITY" in rendered and "'abc'" in rendered and "cycle_time out of range" in rendered


def _save_profile(home: Path, serial: str, offsets: list[int]) -> Path:
    path = RobotProfile.default_path(serial, {"PLEM_HOME": str(home)})
    RobotProfile(robot_serial=serial, joint_offsets=offsets).save(path)
    return path


def test_profile_offsets_apply_when_serial_is_set(isolated_environment: Path):
    path = _save_profile(isolated_environment, "PE07I7E0E001", [-535768, 195386, 191634, 34542, 24035, 21232])
    resolved = resolve_arm_config("indy7_v2", launch_args={"robot_serial": "PE07I7E0E001"})
    assert resolved.config.joint_offsets[0] == -535768
    assert resolved.sources["joint_offsets"].detail == f"profile {path}"
    assert resolved.profile_path == path


def test_profile_beats_offsets_set_in_code_with_a_warning(isolated_environment: Path):
    _save_profile(isolated_environment, "S1", [1, 2, 3, 4, 5, 6])
    resolved = resolve_arm_config("indy7", programmatic={"robot_serial": "S1", "joint_offsets": [9] * 6})
    assert resolved.config.joint_offsets == [1, 2, 3, 4, 5, 6]
    assert any("replaced by the profile" in w for w in resolved.warnings)


def test_offsets_from_code_when_no_serial():
    resolved = resolve_arm_config("indy7", programmatic={"joint_offsets": [9] * 6}, environ={})
    assert resolved.config.joint_offsets == [9] * 6
    assert resolved.sources["joint_offsets"].kind is LayerKind.PROGRAMMATIC


def test_missing_profile_is_the_reference_error():
    with pytest.raises(ProfileError) as error:
        resolve_arm_config("indy7", environ={"PLEM_ROBOT_SERIAL": "NOPE1"})
    assert error.value.summary.startswith("Failed to open profile file")
    assert "plem profile create --serial NOPE1" in error.value.how


def test_profile_with_wrong_joint_count_for_the_model(isolated_environment: Path):
    _save_profile(isolated_environment, "S7", [0] * 7)
    with pytest.raises(ConfigError) as error:
        resolve_arm_config("indy7", launch_args={"robot_serial": "S7"})
    assert error.value.summary == "joint_offsets must have exactly 6 elements"
    assert "profile" in error.value.why


LAYERS = ("programmatic", "launch", "env")
priorities = st.integers(min_value=1, max_value=98)


@settings(max_examples=200, deadline=None)
@given(values=st.fixed_dictionaries({}, optional={layer: priorities for layer in LAYERS}))
def test_highest_layer_always_wins(values):
    resolved = resolve_arm_config(
        "indy7",
        programmatic={"rt_priority": values["programmatic"]} if "programmatic" in values else None,
        launch_args={"rt_priority": str(values["launch"])} if "launch" in values else None,
        environ={"PLEM_RT_PRIORITY": str(values["env"])} if "env" in values else {},
    )
    expected = next((values[layer] for layer in LAYERS if layer in values), 98)
    assert resolved.config.rt_priority == expected
    winner = next((layer for layer in LAYERS if layer in values), "model")
    kinds = {"programmatic": LayerKind.PROGRAMMATIC, "launch": LayerKind.LAUNCH_ARGUMENT,
             "env": LayerKind.ENVIRONMENT, "model": LayerKind.MODEL_DEFAULT}
    assert resolved.sources["rt_priority"].kind is kinds[winner]
