"""The URDF's <limit> values are hard limits: joint_limits.yaml may tighten them, never loosen or remove them.

Validation reports a loosening as an error naming both files; whatever the file says, the limits the driver
enforces are the tighter of the two, down to the commands a robot on the simulated arm sends.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from plem.control.limits import ArmLimits
from plem.description.validate import Stage, validate_package
from plem.errors import PlemError
from plem.fieldbus.mock import MockBus
from plem.robot import Indy7V2, Robot

from .packages import copy_builtin
from .robot_fixtures import RAW_ZERO

JOINTS = tuple(f"joint{i}" for i in range(6))
URDF_VELOCITY = [2.617993878] * 3 + [3.141592654] * 3
URDF_EFFORT = [431.97, 431.97, 197.23, 79.79, 79.79, 79.79]
URDF_POSITION = 3.054326191


def loosening_package(folder: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """indy7_v2 whose joint_limits.yaml switches off joint0's velocity and position limits and joint3's effort
    limit, and allows joint1 twice the URDF's velocity and joint2 a wider range."""
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(folder))
    root = copy_builtin("indy7_v2", folder)
    path = root / "config" / "joint_limits.yaml"
    text = path.read_text(encoding="utf-8")
    entries = re.split(r"(?m)^(?=  joint\d:)", text)
    edits = {1: [("has_velocity_limits: true", "has_velocity_limits: false"),
                 ("has_position_limits: true", "has_position_limits: false")],
             2: [("max_velocity: 2.617993878", "max_velocity: 5.5")],
             3: [("min_position: -3.054326191", "min_position: -3.5")],
             4: [("has_effort_limits: true", "has_effort_limits: false")]}
    for index, replacements in edits.items():
        for old, new in replacements:
            assert old in entries[index]
            entries[index] = entries[index].replace(old, new)
    path.write_text("".join(entries), encoding="utf-8")
    return root


def line_of(path: Path, needle: str, after: str = "") -> int:
    """The 1-based line of the first `needle` after the first line holding `after`."""
    lines = path.read_text(encoding="utf-8").splitlines()
    start = next(number for number, text in enumerate(lines, 1) if after in text)
    return next(number for number, text in enumerate(lines, 1) if number >= start and needle in text)


def test_loosening_is_an_error_naming_both_files_lines_and_values(tmp_path, monkeypatch):
    root = loosening_package(tmp_path, monkeypatch)
    report = validate_package(root)
    assert not report.passed()  # an error, not only under --strict
    yaml_path, urdf_path = root / "config" / "joint_limits.yaml", root / "urdf" / "indy7_v2.urdf.xacro"
    urdf_at = f"({urdf_path}:{line_of(urdf_path, '<limit lower=')})"
    problems = {(p.code, p.summary): p for p in report.findings.errors}
    assert set(problems) == {
        ("limits.removes_urdf", "joint_limits.yaml removes the velocity limit of joint0"),
        ("limits.removes_urdf", "joint_limits.yaml removes the position limit of joint0"),
        ("limits.exceeds_urdf", "joint_limits.yaml loosens the velocity limit of joint1"),
        ("limits.exceeds_urdf", "joint_limits.yaml loosens the lower position limit of joint2"),
        ("limits.removes_urdf", "joint_limits.yaml removes the effort limit of joint3"),
    }
    velocity = problems["limits.exceeds_urdf", "joint_limits.yaml loosens the velocity limit of joint1"]
    assert velocity.location == f"{yaml_path}:{line_of(yaml_path, 'max_velocity: 5.5')}"
    assert velocity.why == f'max_velocity 5.5 is above the URDF\'s velocity="2.61799" {urdf_at}'
    text = velocity.render()
    assert f"WHY: {yaml_path}:{velocity.line}: max_velocity 5.5" in text and urdf_at in text
    removed = problems["limits.removes_urdf", "joint_limits.yaml removes the velocity limit of joint0"]
    assert removed.location == f"{yaml_path}:{line_of(yaml_path, 'has_velocity_limits: false')}"
    assert removed.why == f'has_velocity_limits: false, while the URDF\'s <limit> sets velocity="2.61799" {urdf_at}'
    position = problems["limits.removes_urdf", "joint_limits.yaml removes the position limit of joint0"]
    assert position.line == line_of(yaml_path, "has_position_limits: false")
    assert 'lower="-3.05433" upper="3.05433"' in position.why
    lower = problems["limits.exceeds_urdf", "joint_limits.yaml loosens the lower position limit of joint2"]
    assert lower.line == line_of(yaml_path, "min_position: -3.5") and 'lower="-3.05433"' in lower.why


@pytest.mark.parametrize("stage", [Stage.STARTUP, Stage.FULL])
def test_enforced_limits_are_the_urdfs_whatever_the_file_says(tmp_path, monkeypatch, stage):
    """The merged limits (what the driver gets) keep every URDF limit, also where validation stops at start-up."""
    report = validate_package(loosening_package(tmp_path, monkeypatch), stage=stage)
    limits = ArmLimits.from_joint_limits(report.limits, JOINTS)
    assert limits.max_velocity.tolist() == URDF_VELOCITY
    assert limits.max_effort.tolist() == URDF_EFFORT
    assert limits.min_position.tolist() == [-URDF_POSITION] * 5 + [-3.752457892]
    assert limits.max_position.tolist() == [URDF_POSITION] * 5 + [3.752457892]
    assert report.file_limits["joint0"].max_velocity is None and report.file_limits["joint1"].max_velocity == 5.5


def test_tighter_file_values_are_kept(tmp_path, monkeypatch):
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(tmp_path))
    root = copy_builtin("indy7_v2", tmp_path)
    path = root / "config" / "joint_limits.yaml"
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("max_velocity: 2.617993878", "max_velocity: 1.25", 1)
                    .replace("min_position: -3.054326191", "min_position: -1.5", 1), encoding="utf-8")
    report = validate_package(root)
    assert report.passed(strict=True)
    assert report.limits["joint0"].max_velocity == 1.25 and report.limits["joint0"].min_position == -1.5
    assert report.limits["joint0"].max_position == URDF_POSITION


def test_a_robot_is_not_started_from_a_file_that_loosens_the_urdf(tmp_path, monkeypatch):
    """Start-up runs the same check: the robot is refused before its bus opens, both files named."""
    root = loosening_package(tmp_path, monkeypatch)
    config = Indy7V2()
    config.joint_offsets = [-r for r in RAW_ZERO]
    bus = MockBus(6, raw_zero=RAW_ZERO)
    config.custom_bus = bus
    with pytest.raises(PlemError) as caught:
        Robot.builder(config).with_description(str(root)).build()
    text = caught.value.render()
    assert "removes the velocity limit of joint0" in text and "loosens the velocity limit of joint1" in text
    assert "joint_limits.yaml:" in text and ".urdf.xacro:" in text
    with pytest.raises(PlemError, match="not open"):
        bus.read()   # refused before the bus was opened


def test_a_limit_a_macro_names_is_placed_by_its_line_in_the_rendered_urdf(tmp_path, monkeypatch):
    """When two source joints could have rendered as joint3, the file is named with the rendered URDF's line."""
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(tmp_path))
    root = copy_builtin("indy7_v2", tmp_path)
    urdf = root / "urdf" / "indy7_v2.urdf.xacro"
    text = urdf.read_text(encoding="utf-8")
    text = text.replace('velocity="3.141592654" effort="79.79"/>', 'velocity="nan" effort="79.79"/>', 1)
    text = text.replace("  <!-- ======================= links",
                        '  <xacro:macro name="spare" params="n"><joint name="${pfx}${n}" type="fixed"/></xacro:macro>\n'
                        "  <!-- ======================= links", 1)
    urdf.write_text(text, encoding="utf-8")
    report = validate_package(root)
    (problem,) = [p for p in report.findings.errors if p.code == "urdf.limit_value"]
    rendered = report.urdf_xml.splitlines()
    joint = next(n for n, line in enumerate(rendered, 1) if '<joint name="joint3"' in line)
    limit = next(n for n, line in enumerate(rendered, 1) if n >= joint and "<limit " in line)
    assert problem.file == urdf and problem.line is None
    assert problem.why == f'velocity="nan" is not a finite number (line {limit} of the rendered URDF)'
