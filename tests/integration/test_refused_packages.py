"""Hostile or broken description packages that once launched and then stopped a component are refused by
validation at start-up (what `plem launch` runs), each with WHAT/WHY/HOW naming the file; validation itself
stays bounded in the size of the package."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from plem.core.files import read_regular
from plem.description.controllers import controllers_from
from plem.description.model import Quantity, parse_urdf
from plem.description.parameter_ranges import MAX_UPDATE_RATE
from plem.description.problems import Problem
from plem.description.validate import MAX_LINKS, MAX_MESH_BYTES, Stage, ValidationReport, validate_package
from plem.errors import ConfigError
from plem.launch import LaunchFileError, load_launch_file
from plem.robot.config import MAX_ROBOT_ID_CHARS, robot_id_problem
from tests.e2e.cli import plem_executable
from tests.integration.arm_shapes import generated
from tests.integration.test_broken_packages import describe, line_of, replace, run_validation

NAME = "hostile"
URDF = f"urdf/{NAME}.urdf.xacro"
ROS2_CONTROL = f"urdf/{NAME}.ros2_control.xacro"
SRDF = f"srdf/{NAME}.srdf"
CONTROLLERS = "config/controllers.yaml"
KINEMATICS = "config/kinematics.yaml"
FIRST_CYLINDER = '<cylinder radius="0.05" length="${length}"/>'
BASE_ORIGIN = '<origin xyz="0 0 0.15" rpy="0 0 0"/>'


@pytest.fixture
def arm(tmp_path: Path) -> Path:
    """A generated 6-axis package with an SRDF, controllers.yaml and kinematics.yaml; it passes --strict."""
    return generated(tmp_path, NAME)[0]


def renamed(root: Path, old: str, new: str) -> None:
    """Rename a joint or link in every file of the package (the generated names are written out in full)."""
    for path in root.rglob("*"):
        if path.is_file() and path.suffix in (".xacro", ".srdf", ".yaml"):
            text = path.read_text(encoding="utf-8")
            path.write_text(text.replace(old, new), encoding="utf-8")


def startup(root: Path) -> ValidationReport:
    """What `plem launch` checks before it starts anything."""
    return run_validation(root, stage=Stage.STARTUP)


def refused(report: ValidationReport, code: str, file: str) -> list[Problem]:
    """The errors of `code`, which must exist and name `file`; each renders as WHAT/WHY/HOW."""
    found = [p for p in report.findings.errors if p.code == code]
    assert found, f"expected {code}, found:\n{describe(report.findings.problems)}"
    assert all(p.file is not None and p.file.name == Path(file).name for p in found), describe(found)
    for problem in found:
        text = problem.render()
        assert all(part in text for part in ("WHAT: ", "WHY: ", "HOW: ")), text
    return found


def test_the_generated_arm_passes(arm: Path):
    report = validate_package(arm)
    assert report.passed(strict=True), describe(report.findings.problems)


# -- names -------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name, reason", [
    ("j" * 300, "300 characters"),
    ("joint\u202e1", "only letters, digits"),
    ("joint\u20661", "only letters, digits"),
    ("arm joint", "only letters, digits"),
    ("9joint", "must not start with a digit"),
], ids=["long", "bidi_override", "bidi_isolate", "space", "digit_first"])
def test_actuated_joint_names_are_ros_names(arm: Path, name: str, reason: str):
    renamed(arm, "joint1", name)
    problems = refused(startup(arm), "urdf.name", URDF)
    assert any(reason.split()[0] in p.why for p in problems), describe(problems)
    assert name.isprintable() or all(name not in p.why for p in problems)  # shown escaped, never raw


def test_joint_names_up_to_the_limit_pass(arm: Path):
    renamed(arm, "joint1", "j" * 128)
    report = validate_package(arm)
    assert report.passed(strict=True), describe(report.findings.problems)


def test_link_names_hold_no_invisible_characters(arm: Path):
    renamed(arm, "link2", "link\u202e2")
    problems = refused(startup(arm), "urdf.name", URDF)
    assert "link" in problems[0].why and "\\u202e" in problems[0].why


# -- numbers in the URDF -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("shape", [
    '<cylinder radius="-0.05" length="${length}"/>',
    '<cylinder radius="0.05" length="1e9"/>',
    '<cylinder radius="nan" length="${length}"/>',
    '<box size="0.1 0 0.1"/>',
    '<box size="0.1 0.1"/>',
    '<sphere radius="1e400"/>',
], ids=["negative_cylinder", "huge_cylinder", "nan_cylinder", "flat_box", "two_number_box", "infinite_sphere"])
def test_shapes_have_a_real_size(arm: Path, shape: str):
    replace(URDF, FIRST_CYLINDER, shape)(arm)  # in the macro every link's visual uses
    problem, = refused(startup(arm), "urdf.value", URDF)  # one problem for the value, naming each link
    assert "link 'base_link'" in problem.why and "link 'link6'" in problem.why


@pytest.mark.parametrize("origin", [
    '<origin xyz="nan 0 0.15" rpy="0 0 0"/>', '<origin xyz="1e400 0 0.15" rpy="0 0 0"/>',
    '<origin xyz="0 0 0.15" rpy="0 inf 0"/>', '<origin xyz="0 0 1e6" rpy="0 0 0"/>',
], ids=["nan", "overflow", "infinite_angle", "far"])
def test_origins_are_finite_and_near(arm: Path, origin: str):
    replace(URDF, BASE_ORIGIN, origin)(arm)
    problems = refused(startup(arm), "urdf.value", URDF)
    assert "joint 'joint1'" in problems[0].why and "<origin" in problems[0].why
    assert problems[0].line == line_of(arm / URDF, origin)


def test_every_number_of_a_parsed_urdf_is_kept_for_the_checks():
    urdf = parse_urdf('<robot name="r"><link name="a"><visual><origin xyz="1 2 3"/><geometry><mesh filename="m.stl" '
                      'scale="1 1 1"/></geometry></visual></link></robot>', Path("r.urdf"))
    assert urdf.quantities == [Quantity("link", "a", "origin", "xyz", (1.0, 2.0, 3.0), 3, 1),
                               Quantity("link", "a", "mesh", "scale", (1.0, 1.0, 1.0), 3, 1)]


# -- controllers.yaml and kinematics.yaml ------------------------------------------------------------------------

@pytest.mark.parametrize("rate", ["0", "-500", "1e12", ".inf", ".nan", "fast", "1e400"])
def test_update_rate_is_a_rate_the_loop_can_run(arm: Path, rate: str):
    replace(CONTROLLERS, "update_rate: 1000", f"update_rate: {rate}")(arm)
    problem, = refused(startup(arm), "controllers.update_rate", CONTROLLERS)
    assert problem.line == 6 and f"{MAX_UPDATE_RATE:,}" in problem.what


def test_launch_refuses_update_rate_zero_before_starting(arm: Path):
    replace(CONTROLLERS, "update_rate: 1000", "update_rate: 0")(arm)
    done = subprocess.run([plem_executable(), "launch", f"description_package:={arm}", "bus:=mock",
                           "robot_id:=refused_rate"], check=False, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and "unusable update_rate" in done.stderr, done.stdout + done.stderr
    assert f"{arm / CONTROLLERS}:6: update_rate is 0" in done.stderr


@pytest.mark.parametrize("rate", [0, -1, 1e12, float("inf"), "fast"])
def test_the_controllers_of_a_package_never_carry_an_unusable_rate(rate: object):
    document = {"controller_manager": {"ros__parameters": {"update_rate": rate}}}
    with pytest.raises(ConfigError, match="update_rate"):
        controllers_from(document, ["joint1"], "controllers.yaml")


def test_controller_names_are_ros_names(arm: Path):
    replace(CONTROLLERS, "    arm_controller:\n", "    arm controller/../x:\n")(arm)
    problem, = refused(startup(arm), "controllers.name", CONTROLLERS)
    assert "arm controller/../x" in problem.why and problem.line is not None


@pytest.mark.parametrize("key, value", [
    ("kinematics_solver_timeout", "-1"), ("kinematics_solver_timeout", "1e300"), ("kinematics_solver_timeout", ".nan"),
    ("kinematics_solver_search_resolution", "0"), ("kinematics_solver_attempts", "2.5"),
    ("kinematics_solver_attempts", "100000"),
])
def test_kinematics_settings_are_bounded(arm: Path, key: str, value: str):
    text = (arm / KINEMATICS).read_text(encoding="utf-8")
    old = next(line for line in text.splitlines() if line.strip().startswith(f"{key}:"))
    replace(KINEMATICS, old, old.split(":")[0] + f": {value}")(arm)
    problem, = refused(startup(arm), "kinematics.value", KINEMATICS)
    assert key in problem.what and ("at most" in problem.what or "from 1 to" in problem.what)


# -- XML declarations ----------------------------------------------------------------------------------------------

XXE = '<!DOCTYPE robot [<!ENTITY secret SYSTEM "file:///etc/hostname">]>\n'


def test_an_entity_in_a_ros2_control_param_is_refused(arm: Path):
    replace(ROS2_CONTROL, '<?xml version="1.0"?>\n', '<?xml version="1.0"?>\n' + XXE)(arm)
    replace(ROS2_CONTROL, '<param name="gear_ratio">', '<param name="gear_ratio">&secret;')(arm)
    problem, = refused(startup(arm), "urdf.render", URDF)
    assert "declares a DTD" in problem.summary and ROS2_CONTROL.split("/")[1] in problem.why


def test_a_dtd_in_the_urdf_is_refused(arm: Path):
    replace(URDF, '<?xml version="1.0"?>\n', '<?xml version="1.0"?>\n' + XXE)(arm)
    problem, = refused(startup(arm), "urdf.render", URDF)
    assert "declares a DTD" in problem.summary


def test_a_dtd_in_the_srdf_is_refused(arm: Path):
    replace(SRDF, '<?xml version="1.0"?>\n', '<?xml version="1.0"?>\n' + XXE)(arm)
    problem, = refused(startup(arm), "srdf.xml", SRDF)
    assert "declares a DTD" in problem.summary and "entities secret" in problem.why


def test_cli_refuses_an_entity_without_traceback(arm: Path):
    replace(URDF, '<?xml version="1.0"?>\n', '<?xml version="1.0"?>\n' + XXE)(arm)
    done = subprocess.run([plem_executable(), "validate", str(arm)], check=False, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 1 and "declares a DTD" in done.stdout + done.stderr
    assert "Traceback" not in done.stdout + done.stderr


# -- size --------------------------------------------------------------------------------------------------------

def fixed_links(root: Path, count: int) -> None:
    """`count` more links, each fixed below the one before."""
    chain = "".join(f'<link name="${{pfx}}extra{i}"/><joint name="${{pfx}}extra_joint{i}" type="fixed">'
                    f'<parent link="${{pfx}}{f"extra{i - 1}" if i else "base_link"}"/>'
                    f'<child link="${{pfx}}extra{i}"/></joint>\n' for i in range(count))
    replace(URDF, "</robot>", chain + "</robot>")(root)


def test_a_package_at_the_link_limit_passes(arm: Path):
    links = len(parse_urdf(startup(arm).urdf_xml or "", arm / URDF).links)
    fixed_links(arm, MAX_LINKS - links)
    report = startup(arm)
    assert report.passed(), describe(report.findings.problems)


def test_too_many_links_are_refused_with_the_limit_named(arm: Path):
    fixed_links(arm, MAX_LINKS)
    problem, = refused(startup(arm), "urdf.too_large", URDF)
    assert f"at most {MAX_LINKS}" in problem.why and "links" in problem.why


def test_tree_checks_take_time_in_proportion_to_the_links(arm: Path, monkeypatch: pytest.MonkeyPatch):
    """Each link's parent is looked up a bounded number of times (once walked, it is never walked again)."""
    from plem.description.model import UrdfModel

    fixed_links(arm, 900)
    calls = 0
    parent_of = UrdfModel.parent_of

    def counted(self: UrdfModel, link: str) -> object:
        nonlocal calls
        calls += 1
        return parent_of(self, link)

    monkeypatch.setattr(UrdfModel, "parent_of", counted)
    report = startup(arm)
    assert report.urdf is not None and report.passed(), describe(report.findings.problems)
    assert calls <= 4 * len(report.urdf.links), calls


def test_a_huge_mesh_is_refused(arm: Path):
    mesh = arm / "meshes" / "huge.stl"
    with mesh.open("wb") as handle:
        handle.truncate(MAX_MESH_BYTES + 1)  # sparse: no disk used
    replace(URDF, FIRST_CYLINDER, '<mesh filename="package://hostile_description/meshes/huge.stl"/>')(arm)
    problems = refused(run_validation(arm, stage=Stage.STARTUP), "urdf.mesh_too_large", URDF)
    assert "64.0 MiB" in problems[0].what


# -- files that are not files --------------------------------------------------------------------------------------

def test_an_unreadable_urdf_file_is_a_problem_not_an_internal_error(arm: Path):
    report = run_validation(arm, urdf_file="/proc/self/mem")
    assert report.findings.errors, describe(report.findings.problems)
    with pytest.raises(ConfigError, match="Cannot read /proc/self/mem") as error:
        read_regular(Path("/proc/self/mem"), 1 << 20, "URDF")
    assert "Input/output error" in error.value.why



@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_an_override_that_is_no_regular_file_is_named_as_such(arm: Path, kind: str):
    target = arm / "urdf" / "pipe.urdf.xacro"
    if kind == "fifo":
        os.mkfifo(target)
    report = run_validation(arm, urdf_file=target if kind == "fifo" else "/dev/zero")
    problem, = refused(report, "urdf.override_missing", "pipe.urdf.xacro" if kind == "fifo" else "zero")
    assert "not a regular file" in problem.summary
    assert ("is a FIFO" if kind == "fifo" else "is a character device") in problem.why


# -- robot_id ----------------------------------------------------------------------------------------------------

def test_robot_id_length_is_bounded():
    assert robot_id_problem("a" * MAX_ROBOT_ID_CHARS) is None
    assert f"at most {MAX_ROBOT_ID_CHARS}" in (robot_id_problem("a" * (MAX_ROBOT_ID_CHARS + 1)) or "")


@pytest.mark.parametrize("length", [90, 220])
def test_launch_refuses_a_long_robot_id_up_front(length: int):
    done = subprocess.run([plem_executable(), "launch", "bus:=mock", f"robot_id:={'r' * length}"], check=False,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"at most {MAX_ROBOT_ID_CHARS} characters" in done.stderr and "robot_id" in done.stderr
    assert "Internal error" not in done.stderr and "WHY: None" not in done.stderr


# -- launch files --------------------------------------------------------------------------------------------------

def test_a_launch_file_that_raises_names_its_file_and_line(arm: Path):
    path = arm / "launch" / "bringup.launch.py"
    lines = path.read_text(encoding="utf-8").splitlines()
    at = next(number for number, line in enumerate(lines, 1) if line.startswith("def generate_launch_description"))
    lines.insert(at, "    raise RuntimeError('no bring-up today')")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(LaunchFileError) as error:
        load_launch_file(path)
    assert f"{path}:{at + 1}: RuntimeError: no bring-up today" in error.value.why
    assert f"fix {path}:{at + 1}" in error.value.how


def test_a_launch_file_with_a_syntax_error_names_its_line(arm: Path):
    path = arm / "launch" / "bringup.launch.py"
    path.write_text(path.read_text(encoding="utf-8") + "\ndef broken(:\n", encoding="utf-8")
    count = len(path.read_text(encoding="utf-8").splitlines())
    with pytest.raises(LaunchFileError) as error:
        load_launch_file(path)
    assert f"{path}:{count}: SyntaxError" in error.value.why


def test_launching_a_package_file_warns_that_it_is_trusted(arm: Path):
    path = arm / "launch" / "bringup.launch.py"
    path.write_text("raise SystemExit('stop here')\n", encoding="utf-8")  # no robot needs to start
    done = subprocess.run([plem_executable(), "launch", str(path)], check=False, capture_output=True, text=True,
                          timeout=120, env={**os.environ, "PLEM_PACKAGE_PATH": str(arm.parent)})
    assert "WARNING:" in done.stderr and "trusts that package" in done.stderr, done.stderr
    assert done.returncode == 1 and f"WHY: {path}:1: SystemExit: stop here" in done.stderr, done.stderr

