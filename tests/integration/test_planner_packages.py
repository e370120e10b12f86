"""The planner on the shapes real arms' description packages take: a tiny IK budget (kinematics.yaml), named
states spelled otherwise than `home`, joint limits without acceleration or jerk.

Each package is the built-in Indy7 v2 with one file edited the way an upstream package writes it.
"""

from __future__ import annotations

import threading
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from plem.bridge.planning import PlannerLink
from plem.control.limits import ArmLimits
from plem.description.limits import derived_limits_note
from plem.description.validate import validate_package
from plem.errors import MoveItCode, PlanningError
from plem.ipc.command_socket import listen, remove_own_socket
from plem.planning.goals import NamedGoal, PoseGoal
from plem.planning.planner import Planner
from plem.planning.poses import Pose
from plem.planning.protocol import goal_json
from plem.planning.retiming import fit_to_limits
from plem.planning.service import PlannerService
from plem.robot.robot import home_position
from tests.integration.packages import copy_builtin
from tests.integration.test_planner import CYCLE_S, Arm, failure

Edit = Callable[[Path], None]


def edited(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, *edits: Edit) -> Path:
    """The built-in Indy7 v2 package copied under tmp_path (found first by name), with `edits` applied."""
    folder = tmp_path / "packages"
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(folder))
    root = copy_builtin("indy7_v2", folder)
    for edit in edits:
        edit(root)
    return root


def replace_in(relative: str, old: str, new: str) -> Edit:
    """An edit replacing `old` (which must occur) by `new` in one file of the package."""
    def edit(root: Path) -> None:
        path = root / relative
        text = path.read_text()
        assert old in text, f"{old!r} not in {path}"
        path.write_text(text.replace(old, new))
    return edit


TINY_IK_BUDGET = replace_in("config/kinematics.yaml", "kinematics_solver_timeout: 0.05",
                            "kinematics_solver_timeout: 0.0001")


class Still:
    """An arm state source the requests below never need (each gives its start state)."""

    def live_state(self) -> object:
        raise AssertionError("the requests give their own start state")


@dataclass
class Served:
    """A planner serving on a real planner socket, and a client's link to it."""

    arm: Arm
    service: PlannerService
    link: PlannerLink


@pytest.fixture
def served(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Served]:
    """A planner with a 0.1 ms IK budget serving on a real planner socket, and a client's link to it."""
    arm = Arm(validate_package(edited(tmp_path, monkeypatch, TINY_IK_BUDGET)))
    assert arm.planner.group().settings.timeout_s == 0.0001
    robot_id = f"planner_{uuid.uuid4().hex[:8]}"
    service = PlannerService(arm.planner, Still())  # type: ignore[arg-type]
    server, stop = listen(robot_id, service="planner"), threading.Event()
    serving = threading.Thread(target=service.serve, args=(server, stop), daemon=True)
    serving.start()
    link = PlannerLink(robot_id)
    try:
        yield Served(arm, service, link)
    finally:
        link.close()
        stop.set()
        serving.join(5)
        server.close()
        remove_own_socket(robot_id, "planner")


def test_ik_out_of_time_is_an_answer_and_the_planner_serves_on(served: Served) -> None:
    """With 0.1 ms of IK the time is gone before the goal search starts: that search still runs once and its
    failure is the answer (it was an AssertionError that closed the connection)."""
    arm, link = served.arm, served.link
    start = list(map(float, arm.home))
    far = PoseGoal(Pose((5.0, 0.0, 0.0)))
    with pytest.raises(PlanningError) as caught:
        link.request("plan", start=start, goal=goal_json(far))
    error = caught.value
    assert error.code == MoveItCode.NO_IK_SOLUTION, error.render()
    assert "0.3 ms" in error.why and "closest came within" in error.why
    assert "kinematics_solver_timeout" in error.how and "did not answer" not in error.summary
    near = arm.tool(arm.home)
    plan = link.request("plan", start=start, goal=goal_json(PoseGoal(near, position_only=True)))
    assert plan["fraction"] == 1.0 and plan["points"]
    named = link.request("plan", start=start, goal={"named": "zero"})
    assert named["points"][-1]["positions"] == pytest.approx([0.0] * 6, abs=1e-9)


def test_a_request_that_trips_over_a_bug_is_answered_and_the_planner_serves_on(
        served: Served, monkeypatch: pytest.MonkeyPatch) -> None:
    arm, link = served.arm, served.link
    start = list(map(float, arm.home))

    def broken(*args: object, **kwargs: object) -> object:
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(arm.planner, "fk", broken)
    with pytest.raises(PlanningError) as caught:
        link.request("fk", positions=start, links=["tcp"])
    error = caught.value
    assert error.code == MoveItCode.FAILURE and "fk request" in error.summary
    assert "ZeroDivisionError: float division by zero" in error.why and error.how
    monkeypatch.undo()
    answer = link.request("fk", positions=start, links=["tcp"])
    assert answer["tcp"]["position"] == pytest.approx(list(arm.tool(arm.home).position))
    monkeypatch.setitem(served.service._operations, "describe", lambda request: {"value": object()})
    with pytest.raises(PlanningError) as caught:  # a result JSON cannot carry is that request's error
        link.request("describe")
    assert "TypeError" in caught.value.why and "answer request" in caught.value.summary
    monkeypatch.undo()
    assert link.request("describe")["joint_names"] == list(arm.joint_names)


SRDF = "srdf/indy7_v2.srdf"
HOME_POS = replace_in(SRDF, '<group_state name="home"', '<group_state name="HomePos"')  # indy-ros2's name
KINOVA_HOME = replace_in(SRDF, '<group_state name="home"', '<group_state name="Home"')
#: The SRDF's own `zero`, spelled otherwise and not at 0 rad: it wins over plem's every-joint-at-0.
OWN_ZERO = replace_in(SRDF, '''<group_state name="zero" group="arm">
    <joint name="joint0" value="0"/>''', '''<group_state name="Zero" group="arm">
    <joint name="joint0" value="0.25"/>''')


def test_names_match_the_srdf_exactly_then_ignoring_case_and_nothing_is_made_up(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    report = validate_package(edited(tmp_path, monkeypatch, HOME_POS, OWN_ZERO))
    assert report.urdf is not None
    joints = tuple(joint.name for joint in report.urdf.actuated_joints)
    planner = Planner.for_package(report, joints, ArmLimits.from_joint_limits(report.limits, joints), CYCLE_S)
    assert sorted(planner.named_states) == ["HomePos", "Zero"]
    start = np.zeros(6)
    start[2] = start[4] = -1.0
    error = failure(lambda: planner.plan(start, NamedGoal("home")))
    assert error.code == MoveItCode.INVALID_GOAL_CONSTRAINTS and "HomePos, Zero" in error.what
    assert "group_state" in error.how
    assert home_position(report, joints) is None  # the simulated arm then starts by its other rules
    to_home_pos = planner.plan(start, NamedGoal("homepos"))
    np.testing.assert_allclose(to_home_pos.trajectory.points[-1].positions, planner.named_states["HomePos"])
    to_zero = planner.plan(start, NamedGoal("zero"))
    assert to_zero.trajectory.points[-1].positions[0] == pytest.approx(0.25)


def test_home_in_another_case_is_home_and_zero_is_every_joint_at_zero(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    report = validate_package(edited(tmp_path, monkeypatch, KINOVA_HOME, replace_in(
        SRDF, '<group_state name="zero"', '<group_state name="HOME"')))
    assert report.urdf is not None
    joints = tuple(joint.name for joint in report.urdf.actuated_joints)
    planner = Planner.for_package(report, joints, ArmLimits.from_joint_limits(report.limits, joints), CYCLE_S)
    assert sorted(planner.named_states) == ["HOME", "Home", "zero"]
    np.testing.assert_allclose(planner.named_states["zero"], np.zeros(6))
    error = failure(lambda: planner.plan(np.zeros(6), NamedGoal("home")))
    assert "Home, HOME differ from 'home' only in case" in error.why and "exactly" in error.how
    moved = planner.plan(np.zeros(6), NamedGoal("Home"))
    np.testing.assert_allclose(moved.trajectory.points[-1].positions, planner.named_states["Home"])
    assert home_position(report, joints) is None  # ambiguous: no guess


def test_the_simulated_arm_finds_home_as_plem_move_does(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    report = validate_package(edited(tmp_path, monkeypatch, KINOVA_HOME))
    assert report.urdf is not None and report.srdf is not None
    joints = tuple(joint.name for joint in report.urdf.actuated_joints)
    assert home_position(report, joints) == tuple(report.srdf.poses(joints)["Home"])


def without(*keys: str, joints: tuple[str, ...] = ()) -> Edit:
    """An edit dropping `keys` (and their has_*_limits switches) from joint_limits.yaml: for `joints`, else all."""
    def edit(root: Path) -> None:
        path = root / "config" / "joint_limits.yaml"
        document = yaml.safe_load(path.read_text())
        for name, entry in document["joint_limits"].items():
            if not joints or name in joints:
                for key in keys:
                    entry.pop(key, None)
                    entry.pop(f"has_{key.removeprefix('max_')}_limits", None)
        path.write_text(yaml.safe_dump(document, sort_keys=False))
    return edit


@pytest.mark.parametrize("left_out", [("max_jerk",), ("max_acceleration", "max_jerk")], ids="+".join)
def test_limits_a_package_leaves_out_are_derived_stated_and_kept_by_every_plan(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, left_out: tuple[str, ...]) -> None:
    """Planned with the limits the core enforces, a plan runs exactly as sent: the command path neither slows nor
    smooths it (without max_jerk, plans were re-timed 1.6x by the driver while saying every limit was kept)."""
    report = validate_package(edited(tmp_path, monkeypatch, without(*left_out)))
    arm = Arm(report)
    limits = arm.limits
    acceleration = limits.max_velocity / 0.5 if "max_acceleration" in left_out else np.full(6, 3.0)
    np.testing.assert_allclose(limits.max_acceleration, acceleration)
    np.testing.assert_allclose(limits.max_jerk, acceleration / 0.1)
    warnings = [problem for problem in report.findings.warnings if problem.code == "limits.incomplete"]
    assert len(warnings) == 6
    assert f"max_jerk {acceleration[0] / 0.1:.4g} rad/s³ (max_acceleration / 0.1 s)" in warnings[0].how
    assert ("max_acceleration 5.236 rad/s² (max_velocity / 0.5 s)" in warnings[0].how) == (len(left_out) == 2)
    note = derived_limits_note(report.limits)
    assert "max_jerk = max_acceleration / 0.1 s (joint0 " in note and "config/joint_limits.yaml" in note

    start = np.array([0.5, -1.0, 1.0, 0.3, 0.2, 0.1])
    rest = np.zeros(6)
    pose = arm.tool(arm.home)
    plans = [arm.planner.plan(start, NamedGoal("home")), arm.planner.plan(start, PoseGoal(pose)),
             arm.planner.cartesian(arm.home, [Pose((pose.position[0], pose.position[1], pose.position[2] - 0.2),
                                                   pose.orientation)])]
    for plan, begin in zip(plans, (start, start, arm.home), strict=True):
        assert "every limit kept" in plan.summary()
        timed = fit_to_limits(plan.trajectory, limits, (begin, rest, rest), CYCLE_S)
        assert timed.change == "", timed.note()
        assert timed.motion.duration == pytest.approx(plan.duration_s, abs=1e-9)


def test_a_group_joint_without_a_velocity_limit_cannot_be_planned_for() -> None:
    indy7 = Arm(validate_package("indy7_v2_description"))
    velocities = indy7.limits.max_velocity.copy()
    velocities[2] = np.inf
    report = indy7.report
    assert report.urdf is not None and report.srdf is not None and report.urdf_xml is not None
    planner = Planner(report.urdf_xml, report.urdf, report.srdf, indy7.joint_names,
                      replace(indy7.limits, max_velocity=velocities), CYCLE_S)
    error = failure(lambda: planner.plan(indy7.home, NamedGoal("zero")))
    assert "joint2" in error.why and "max_velocity" in error.how and "joint_limits.yaml" in error.how
