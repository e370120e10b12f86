import pytest

from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.description.discover import package_for_launch
from plem.description.drives import drive_parameters
from plem.description.model import parse_urdf
from plem.description.render import render_xacro
from plem.description.validate import validate_package
from plem.robot import MODELS
from tests.integration.packages import BUILTIN_TYPES


@pytest.mark.parametrize("robot_type", BUILTIN_TYPES)
def test_builtin_package_passes_strict(robot_type):
    report = validate_package(f"{robot_type}_description")
    assert report.findings.problems == []
    assert report.passed(strict=True)
    assert report.dof == MODELS[robot_type].MODEL.dof
    assert [j.name for j in report.urdf.actuated_joints] == list(MODELS[robot_type].MODEL.joint_names)
    assert report.srdf is not None and "arm" in report.srdf.groups


@pytest.mark.parametrize("robot_type", BUILTIN_TYPES)
def test_prefix_renames_every_link_and_joint(robot_type):
    urdf = next((BUILTIN_PACKAGES_DIR / f"{robot_type}_description" / "urdf").glob("*.urdf.xacro"))
    plain = parse_urdf(render_xacro(urdf), urdf)
    prefixed = parse_urdf(render_xacro(urdf, {"prefix": "left_"}), urdf)
    assert sorted(prefixed.joints) == sorted(f"left_{name}" for name in plain.joints)
    assert sorted(prefixed.links) == sorted(f"left_{name}" for name in plain.links)
    expected = [f"left_{j.name}" for j in plain.actuated_joints]
    assert [j.name for b in prefixed.ros2_control for j in b.joints] == expected


@pytest.mark.parametrize("robot_type", BUILTIN_TYPES)
def test_drive_parameters_match_the_model_preset(robot_type):
    """Every joint declares its drive; the counts per radian are the preset's, without EtherCAT identities."""
    model = MODELS[robot_type].MODEL
    report = validate_package(f"{robot_type}_description")
    drives = drive_parameters(report.urdf, model.joint_names)
    assert drives is not None and len(drives) == model.dof
    assert [d.counts_per_radian for d in drives] == pytest.approx(model.counts_per_radian(), rel=1e-15)
    assert [d.encoder_resolution for d in drives] == list(model.encoder_counts_per_rev)
    assert [d.gear_ratio for d in drives] == list(model.gear_ratios)
    assert all(d.direction == 1 and d.vendor_id is d.product_code is d.revision is None for d in drives)


@pytest.mark.parametrize("description_package, robot_type, expected", [
    (None, None, "indy7_v2_description"),
    ("wim_description", "indy12", "indy12_description"),
    (None, "indyrp2_v2", "indyrp2_v2_description"),
    ("my_robot_description", "indy12", "my_robot_description"),
])
def test_launch_package_selection(description_package, robot_type, expected):
    assert package_for_launch(description_package, robot_type) == expected
