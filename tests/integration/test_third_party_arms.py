"""Real third-party arms (UR5, Franka Panda from example-robot-data), wrapped in the protocol at test time, validate."""

from __future__ import annotations

from pathlib import Path

import pytest
from lxml import etree

from plem.description.render import render_xacro
from plem.description.validate import validate_package
from tests.third_party import ARMS, DATA_PACKAGE, REFERENCE_ATTRIBUTES, WrappedArm, wrap


@pytest.fixture(params=ARMS, ids=lambda spec: spec.name)
def wrapped_arm(request: pytest.FixtureRequest, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> WrappedArm:
    return wrap(request.param, tmp_path, monkeypatch)



def test_wrapped_arm_validates_with_only_the_drive_warning(wrapped_arm: WrappedArm) -> None:
    """example-robot-data gives no drive data, so the wrapper declares none: that warning and nothing else."""
    report = validate_package(wrapped_arm.spec.package)
    problems = [problem for problem in report.findings.problems if problem.code != "drive.none"]
    assert not problems, "\n\n".join(problem.render() for problem in problems)
    assert [problem.code for problem in report.findings.warnings] == ["drive.none"] and report.passed()
    assert report.dof == wrapped_arm.spec.dof
    assert report.files.root == wrapped_arm.root
    meshes = [uri for uri, _ in report.urdf.meshes]
    assert meshes and all(uri.startswith(f"package://{DATA_PACKAGE}/") for uri in meshes), meshes


def test_prefix_renames_every_link_joint_and_hardware_joint(wrapped_arm: WrappedArm) -> None:
    robot = etree.fromstring(render_xacro(wrapped_arm.urdf_xacro, {"prefix": "left_"}).encode("utf-8"))
    assert [el.get("name") for el in robot.findall("link")] == [f"left_{name}" for name in wrapped_arm.links]
    assert [el.get("name") for el in robot.findall("joint")] == [f"left_{name}" for name in wrapped_arm.joints]
    references = [el.get(attribute) for el in robot.iter(etree.Element) for attribute in REFERENCE_ATTRIBUTES
                  if el.get(attribute) is not None] + [el.get("name") for el in robot.iter("joint")]
    assert references and all(reference.startswith("left_") for reference in references), references
    (block,) = robot.findall("ros2_control")
    assert block.get("name") == f"left_{wrapped_arm.spec.name}_hardware"
    assert [el.get("name") for el in block.findall("joint")] == [f"left_{j.name}" for j in wrapped_arm.actuated]
