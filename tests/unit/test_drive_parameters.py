"""Drive parameters: the ros2_control <param> tags parsed into DriveParameters, and every malformed or partial
declaration refused with a ConfigError naming the joint, the parameter and the line to write."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest

from plem.description.drives import (
    PARAMS,
    REQUIRED,
    DriveParameters,
    ParamSources,
    check_drive_parameters,
    drive_parameters,
)
from plem.description.model import UrdfModel, parse_urdf
from plem.errors import ConfigError

JOINTS = ["joint0", "joint1", "joint2"]
GOOD = {"encoder_resolution": "65536", "gear_ratio": "121", "direction": "1"}


def urdf(joints: dict[str, dict[str, str]], hardware: dict[str, str] | None = None) -> UrdfModel:
    """A URDF whose ros2_control block has `joints` (name -> params); line numbers as parse_urdf sees them."""
    body = "".join(
        f'  <joint name="{name}">\n'
        + "".join(f'    <param name="{key}">{value}</param>\n' for key, value in params.items())
        + '    <command_interface name="position"/>\n    <state_interface name="position"/>\n  </joint>\n'
        for name, params in joints.items())
    hardware_params = "".join(f'<param name="{k}">{v}</param>' for k, v in (hardware or {}).items())
    text = (f'<robot name="arm">\n<ros2_control name="hw" type="system">\n'
            f"  <hardware><plugin>hardware/HardwareInterface</plugin>{hardware_params}</hardware>\n{body}"
            "</ros2_control>\n</robot>\n")
    return parse_urdf(text, Path("arm.urdf.xacro"))


def every(params: dict[str, str]) -> dict[str, dict[str, str]]:
    return {name: dict(params) for name in JOINTS}


def refused(model: UrdfModel, joints: list[str] = JOINTS, **kwargs) -> ConfigError:
    with pytest.raises(ConfigError) as caught:
        drive_parameters(model, joints, **kwargs)
    return caught.value


# ---------------------------------------------------------------- parsing

def test_params_and_their_lines_are_parsed():
    model = urdf({"joint0": {"gear_ratio": "  121 ", "direction": "-1"}}, hardware={"bus": "ethercat"})
    (block,) = model.ros2_control
    (joint,) = block.joints
    assert joint.params == {"gear_ratio": "121", "direction": "-1"}
    assert joint.param_lines == {"gear_ratio": 5, "direction": 6}
    assert block.params == {"bus": "ethercat"} and block.param_lines == {"bus": 3}


def test_the_last_param_of_a_name_wins_as_in_ros2_control():
    text = ('<robot name="r"><ros2_control name="hw"><joint name="j"><param name="direction">1</param>'
            '<param name="direction">-1</param></joint></ros2_control></robot>')
    (joint,) = parse_urdf(text, Path("r.urdf")).ros2_control[0].joints
    assert joint.params == {"direction": "-1"}


def test_parameters_in_joint_order():
    model = urdf({"joint0": GOOD, "joint1": {**GOOD, "gear_ratio": "101", "direction": "-1"},
                  "joint2": {**GOOD, "encoder_resolution": "131072", "gear_ratio": "50.5"}})
    drives = drive_parameters(model, ["joint2", "joint0", "joint1"])
    assert drives == (DriveParameters(131072, 50.5, 1), DriveParameters(65536, 121.0, 1),
                      DriveParameters(65536, 101.0, -1))
    assert all(isinstance(d.encoder_resolution, int) and isinstance(d.direction, int) for d in drives)


def test_no_parameters_at_all_is_none():
    assert drive_parameters(urdf(every({})), JOINTS) is None
    assert check_drive_parameters(urdf(every({})), JOINTS) == []


def test_unknown_params_alone_declare_nothing_and_are_only_warned():
    model = urdf({"joint0": {"zero_offset": "12"}, "joint1": {}, "joint2": {}})
    assert drive_parameters(model, JOINTS) is None
    (problem,) = check_drive_parameters(model, JOINTS)
    assert (problem.code, problem.error, problem.joint, problem.param) == ("drive.unknown_param", False, "joint0",
                                                                         "zero_offset")
    assert all(name in problem.what for name in PARAMS)


@pytest.mark.parametrize("vendor_id, product_code, revision, expected", [
    ("0x0000066F", "0x00000001", "0x00010000", (0x66F, 1, 0x10000)),
    ("1647", "0", "4294967295", (1647, 0, 0xFFFFFFFF)),
    ("0XFFFFFFFF", "0xabcdef", "007", (0xFFFFFFFF, 0xABCDEF, 7)),
])
def test_identity_in_hex_or_decimal(vendor_id, product_code, revision, expected):
    params = {**GOOD, "vendor_id": vendor_id, "product_code": product_code, "revision": revision}
    drive = drive_parameters(urdf(every(params)), JOINTS)[0]
    assert (drive.vendor_id, drive.product_code, drive.revision) == expected


def test_identity_is_optional_per_joint():
    model = urdf({"joint0": {**GOOD, "vendor_id": "0x2"}, "joint1": GOOD, "joint2": GOOD})
    drives = drive_parameters(model, JOINTS)
    assert [d.vendor_id for d in drives] == [2, None, None] and drives[1].product_code is None


def test_rated_torque_is_optional_per_joint_in_newton_metres():
    model = urdf({"joint0": {**GOOD, "rated_torque": "2.5"}, "joint1": GOOD, "joint2": GOOD})
    assert [d.rated_torque for d in drive_parameters(model, JOINTS)] == [2.5, None, None]


@pytest.mark.parametrize("direction", ["1", "+1", "-1"])
def test_direction_accepts_plus_and_minus_one(direction):
    assert drive_parameters(urdf(every({**GOOD, "direction": direction})), JOINTS)[0].direction == int(direction)


def test_counts_per_radian():
    drive = DriveParameters(encoder_resolution=65536, gear_ratio=121.0, direction=-1)
    assert drive.counts_per_radian == pytest.approx(65536 * 121 / (2 * math.pi))
    assert drive.counts_per_radian > 0
    assert drive.signed_counts_per_radian == -drive.counts_per_radian
    assert DriveParameters(4096, 1.0, 1).signed_counts_per_radian == pytest.approx(4096 / (2 * math.pi))


# ---------------------------------------------------------------- refused

MALFORMED = [
    ("encoder_resolution", value) for value in ("0", "-65536", "65536.0", "6.5e4", "1_000", "0x10000", "many", "",
                                                "9" * 5000)
] + [
    ("gear_ratio", value) for value in ("0", "-121", "0.0", "nan", "inf", "-inf", "1e999", "fast", "")
] + [
    ("direction", value) for value in ("0", "2", "-2", "1.0", "forward", "")
] + [
    (name, value) for name in ("vendor_id", "product_code", "revision")
    for value in ("-1", "+5", "4294967296", "0x100000000", "0x", "0xZZ", "12ab", "1.0", "")
] + [
    ("rated_torque", value) for value in ("0", "-1.27", "nan", "inf", "1.27Nm", "")
]


@pytest.mark.parametrize("param, value", MALFORMED)
def test_malformed_value_names_joint_param_value_and_fix(param, value):
    model = urdf({"joint0": GOOD, "joint1": {**GOOD, param: value}, "joint2": GOOD})
    error = refused(model)
    assert "joint1" in error.summary and param in error.summary
    assert repr(value) in error.why
    assert f'<param name="{param}">{PARAMS[param].example}</param>' in error.how
    assert error.what.startswith(param)
    line = model.ros2_control[0].joints[1].param_lines[param]
    assert error.why.endswith(f"(line {line} of the rendered URDF)")  # no package files given


@pytest.mark.parametrize("missing", [["gear_ratio"], ["encoder_resolution", "direction"], list(REQUIRED)])
def test_partly_declared_names_joint_and_the_lines_to_add(missing):
    partial = {key: value for key, value in GOOD.items() if key not in missing}
    error = refused(urdf({"joint0": GOOD, "joint1": GOOD, "joint2": partial}))
    assert "joint2" in error.summary and all(name in error.summary for name in missing)
    assert '<joint name="joint2">' in error.how
    assert all(f'<param name="{name}">' in error.how for name in missing)
    assert not any(f'<param name="{name}">' in error.how for name in REQUIRED if name not in missing)
    if missing == list(REQUIRED):
        assert "joint0 declares drive parameters" in error.why


def test_identity_alone_declares_parameters():
    error = refused(urdf({"joint0": {"vendor_id": "0x2"}, "joint1": {}, "joint2": {}}))
    assert "joint0" in error.summary and "encoder_resolution" in error.summary


def test_joint_outside_ros2_control_when_others_declare():
    error = refused(urdf(every(GOOD)), [*JOINTS, "joint3"])
    assert "joint3" in error.summary and "not in <ros2_control>" in error.why
    assert '<joint name="joint3">' in error.how and "</joint>" in error.how


def test_unknown_param_does_not_stop_the_drive():
    assert drive_parameters(urdf(every({**GOOD, "zero_offset": "0"})), JOINTS)[0] == DriveParameters(65536, 121.0, 1)


def test_check_lists_every_problem():
    model = urdf({"joint0": {**GOOD, "gear_ratio": "-1", "direction": "0"}, "joint1": {"encoder_resolution": "x"},
                  "joint2": {**GOOD, "gain": "3"}})
    found = [(p.code, p.joint, p.param, p.error) for p in check_drive_parameters(model, JOINTS)]
    assert found == [("drive.invalid", "joint0", "gear_ratio", True), ("drive.invalid", "joint0", "direction", True),
                     ("drive.invalid", "joint1", "encoder_resolution", True),
                     ("drive.incomplete", "joint1", None, True), ("drive.unknown_param", "joint2", "gain", False)]


# ---------------------------------------------------------------- the line in the package's files

SOURCE = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="arm_ros2_control" params="prefix:=''">
    <ros2_control name="${prefix}hw" type="system">
      <joint name="${prefix}joint0">
        <param name="encoder_resolution">65536</param>
        <param name="gear_ratio">121</param>
      </joint>
      <joint name="${prefix}joint1">
        <param name="direction">1</param>
      </joint>
    </ros2_control>
  </xacro:macro>
</robot>
"""
MACRO = """  <xacro:macro name="drive" params="name">
    <joint name="${prefix}${name}"><param name="gear_ratio">${gear}</param></joint>
  </xacro:macro>
</robot>
"""


def test_errors_name_the_source_file_and_line(tmp_path: Path):
    source = tmp_path / "arm.ros2_control.xacro"
    source.write_text(SOURCE, encoding="utf-8")
    model = urdf({"joint0": {**GOOD, "gear_ratio": "-121"}, "joint1": GOOD, "joint2": GOOD})
    error = refused(model, sources=[source, None])
    assert error.why.startswith(f"{source}:7: ")
    assert "rendered URDF" not in error.why
    incomplete = refused(urdf({"joint0": GOOD, "joint1": {"direction": "1"}, "joint2": GOOD}), sources=[source])
    assert incomplete.why.startswith(f"{source}:9: ")  # the joint the parameters go into
    assert ParamSources([source]).locate("left_joint1", "direction") == (source, 10)


def test_joints_a_macro_names_are_located_by_file_only(tmp_path: Path):
    source = tmp_path / "arm.ros2_control.xacro"
    source.write_text(SOURCE.removesuffix("</robot>\n") + MACRO, encoding="utf-8")
    locate = ParamSources([None, source]).locate
    assert locate("joint0", "gear_ratio") == (source, None)  # matches both ${prefix}joint0 and ${prefix}${name}
    assert locate("wrist", "gear_ratio") == (source, 15)
    assert ParamSources([tmp_path / "missing.xacro"]).locate("joint0", None) == (tmp_path / "missing.xacro", None)
    assert ParamSources([]).locate("joint0", None) == (None, None)


def test_only_regular_files_are_searched(tmp_path: Path):
    """A FIFO or a folder named like a xacro file is not opened (a FIFO would block the validator)."""
    fifo, folder = tmp_path / "fifo.ros2_control.xacro", tmp_path / "dir.ros2_control.xacro"
    os.mkfifo(fifo)
    folder.mkdir()
    assert ParamSources([fifo, folder]).locate("joint0", "gear_ratio") == (fifo, None)
