"""Reactions evaluated in the core, the contact stop, and the payload, on a simulated arm pushed through its
simulator (a wrench on a link, through the arm's Jacobian) and carrying a payload on its last link."""

from __future__ import annotations

import numpy as np
import pytest

from plem.control.commands import ArmReaction, CommandHandle
from plem.control.compiled import CONSTANTS
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.motion import plan_stop
from plem.control.payload import Payload
from plem.control.reactions import Condition, FreeDrive, Hold, Measure, MoveTo, Record, Stop
from plem.control.trajectory import JointTrajectory, TrajectoryOutcome
from plem.errors import CommandRejected, PlemError
from plem.fieldbus.bus import DriveState
from plem.fieldbus.mock import MockBus
from plem.robot import Indy7V2, Robot
from tests.integration.robot_fixtures import RAW_ZERO, Trace, simulated_robot


@pytest.fixture
def robot() -> Robot:
    robot = simulated_robot()
    robot.set_mode("hold")
    return robot


def _wrench_by_cycle(robot: Robot, cycles: int) -> dict[int, np.ndarray]:
    """Step `cycles` cycles, keeping the wrench the core estimated in each."""
    seen = {}
    for _ in range(cycles):
        robot.step()
        seen[robot.runtime.cycle_count - 1] = robot.stream_status().wrench.copy()
    return seen


def test_a_push_fires_a_standing_reaction_in_the_cycle_that_measures_it(robot: Robot) -> None:
    robot.on(Measure.FORCE_X > 20.0, Record())
    robot.step(50)
    assert np.allclose(robot.stream_status().wrench, 0.0, atol=1e-6)
    robot.bus.push("link6", force=(30.0, 0.0, 0.0))
    seen = _wrench_by_cycle(robot, 100)
    first = min(cycle for cycle, wrench in seen.items() if wrench[0] > 20.0)
    fired = [e for e in robot.events.recent({EventKind.REACTION})]
    assert len(fired) == 1 and fired[0].cycle == first    # no cycle between measuring it and acting
    assert "force x > 20 N" in fired[0].reason and "record" in fired[0].reason
    assert robot.stream_status().wrench[0] == pytest.approx(30.0, abs=0.5)
    robot.bus.release()


def test_until_stops_a_motion_which_succeeds_and_the_arm_holds(robot: Robot) -> None:
    start = robot.state().position.copy()
    handle = robot.move_joints(start + 0.8, speed_scale=0.3, until=Measure.FORCE_X > 20.0)
    robot.step(400)
    robot.bus.push("link6", force=(40.0, 0.0, 0.0))
    result = handle.wait(10.0)
    robot.bus.release()
    assert result.outcome is TrajectoryOutcome.SUCCEEDED and "until condition: force x > 20 N" in result.message
    assert robot.mode is Mode.HOLD and robot.fault_reason == ""
    assert not np.allclose(robot.state().command_position, start + 0.8, atol=1e-3)


def test_an_until_condition_true_from_the_start_stops_the_motion_after_its_first_cycle(robot: Robot) -> None:
    start = robot.state().position.copy()
    begun = robot.runtime.cycle_count
    handle = robot.move_joints(start + 0.8, until=Measure.position(0) > start[0] - 1.0)
    result = handle.wait(10.0)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED and "until condition" in result.message
    started = [e for e in robot.events.recent({EventKind.MOTION_STARTED}) if e.cycle >= begun]
    fired = [e for e in robot.events.recent({EventKind.REACTION}) if e.cycle >= begun]
    assert len(started) == 1 and len(fired) == 1
    assert fired[0].cycle == started[0].cycle + 1   # the first measurement after the motion's first command
    assert np.max(np.abs(robot.state().command_position - start)) < 1e-3


def test_an_until_condition_of_a_refused_motion_is_disarmed_with_it() -> None:
    robot = simulated_robot()   # idle: the motion is refused
    robot.step(5)
    with pytest.raises(CommandRejected):
        robot.move_joints(robot.state().position + 0.1, until=Measure.FORCE_X > 20.0)
    robot.step(2)
    assert robot.runtime.arm[0]["reacting"] == 0
    assert not any(slot["armed"] for slot in robot.runtime.arm[0]["reactions"])


def test_a_digital_input_stops_a_motion_in_the_cycle_the_drive_reports_it(robot: Robot) -> None:
    start = robot.state().position.copy()
    handle = robot.move_joints(start + 0.8, speed_scale=0.3, until=Measure.digital_input("joint5", 16) == 1)
    robot.on(Measure.digital_input(5, 16) == 1, Record(), once=True)   # marks the cycle that saw it
    robot.bus.set_digital_inputs(5, 1 << 15)   # another input: nothing happens
    robot.step(300)
    assert not handle.done
    robot.bus.set_digital_inputs(5, 1 << 16 | 1 << 15)
    result = handle.wait(10.0)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED and "digital input 16 of joint5 == 1" in result.message
    until, record = robot.events.recent({EventKind.REACTION})   # both fired in the cycle that first saw it
    stopped = [e for e in robot.events.recent({EventKind.MOTION_FINISHED}) if e.cycle >= record.cycle]
    assert until.cycle == record.cycle == stopped[0].cycle   # no cycle between seeing the input and stopping
    assert list(robot.bus.digital_inputs[:6]) == [0, 0, 0, 0, 0, 1 << 16 | 1 << 15]


@pytest.mark.parametrize(("make", "words"), [
    (lambda: Measure.digital_input(5, 32), "not a digital input's bit"),
    (lambda: Measure.digital_input(5, True), "not a digital input's bit"),
])
def test_a_bad_digital_input_is_refused(make, words: str) -> None:
    with pytest.raises(CommandRejected) as refused:
        make()
    assert words in refused.value.summary


def test_actions_retract_pause_and_free_drive(robot: Robot) -> None:
    start = robot.state().position.copy()
    retract = start.copy()
    retract[1] -= 0.2
    reaction = robot.on((Measure.FORCE_X > 20.0) & ~(Measure.FORCE_Y > 100.0), MoveTo(retract.tolist()), once=True)
    robot.bus.push("link6", force=(30.0, 0.0, 0.0))
    robot.step(20)
    robot.bus.release()
    robot.step(3000)
    assert np.allclose(robot.state().command_position, retract, atol=1e-9) and robot.mode is Mode.HOLD
    reaction.remove()

    handle = robot.move_joints(start, speed_scale=0.3)
    robot.on(Measure.MOTION_TIME > 0.5, Hold(), once=True)
    robot.step(1500)
    assert robot.mode is Mode.TRAJECTORY and robot.speed_override == 0.0 and not handle.done
    robot.set_speed_override(1.0)
    handle.wait(30.0)

    robot.on(Measure.FORCE_X > 20.0, FreeDrive(), once=True)
    robot.bus.push("link6", force=(30.0, 0.0, 0.0))
    robot.step(20)
    robot.bus.release()
    assert robot.mode is Mode.FREE_DRIVE


def test_the_contact_stop_faults_naming_the_joint_and_a_reset_does_not_move_the_arm(robot: Robot) -> None:
    robot.move_joints(robot.state().position + 0.5, speed_scale=0.2)
    robot.step(300)
    robot.bus.push("link6", force=(150.0, 0.0, 0.0))
    robot.step(200)
    assert robot.mode is Mode.FAULT
    assert "contact: the external torque on joint" in robot.fault_reason and "past its contact threshold" in \
        robot.fault_reason
    robot.bus.release()
    robot.step(1000)
    before = robot.state().position.copy()
    robot.reset_fault()
    robot.step(10)
    after = robot.state()
    assert after.mode is Mode.HOLD
    assert np.allclose(after.command_position, after.position, atol=1e-3)
    assert np.allclose(after.position, before, atol=1e-3)


def test_a_payload_is_estimated_within_5_percent_and_set_payload_explains_its_torque(robot: Robot) -> None:
    bent = robot.state().position.copy()
    bent[[1, 2]] = 0.6, 0.8   # the payload's weight across the joints' axes
    robot.move_joints(bent.tolist()).wait(30.0)
    robot.bus.mount_payload(Payload(2.5, (0.01, 0.0, 0.06)))
    robot.step(500)
    unexplained = np.abs(robot.stream_status().external_torque).max()
    estimated = robot.estimate_payload(apply=False)
    assert estimated.mass == pytest.approx(2.5, rel=0.05)
    assert np.allclose(estimated.com, (0.01, 0.0, 0.06), atol=0.005)
    robot.set_payload(estimated.mass, estimated.center_of_mass)
    robot.step(500)
    assert unexplained > 1.0 and np.abs(robot.stream_status().external_torque).max() < 0.05 * unexplained


@pytest.mark.parametrize(("build", "words"), [
    (lambda r: r.on(Measure.position("elbow") > 1.0, Stop()), "names no joint"),
    (lambda r: r.on((Measure.FORCE_X > 1.0) and (Measure.FORCE_Y > 1.0), Stop()), "no truth value"),
    (lambda r: r.on(Measure.FORCE_X > float("nan"), Stop()), "not a finite number"),  # noqa: SIM300 - a condition
    (lambda r: r.on(Measure.FORCE_X > 1.0, MoveTo([0.0, 0.0])), "one finite position per joint"),
    (lambda r: r.on(Measure.FORCE_X > 1.0, "stop"), "not a reaction action"),
    (lambda r: r.set_payload(-1.0), "mass"),
])
def test_bad_reactions_and_payloads_are_refused_with_what_why_how(robot: Robot, build, words: str) -> None:
    with pytest.raises(PlemError) as raised:
        build(robot)
    assert words in str(raised.value) and "HOW" in str(raised.value)


def _expression(rng: np.random.Generator, atoms: list[tuple[Condition, bool]], depth: int) -> tuple[Condition, bool]:
    """A random condition over atoms of known truth, and its truth as Python evaluates the same combination."""
    if depth == 0 or rng.random() < 0.25:
        return atoms[int(rng.integers(len(atoms)))]
    kind = int(rng.integers(3))
    left, left_truth = _expression(rng, atoms, depth - 1)
    if kind == 0:
        return ~left, not left_truth
    right, right_truth = _expression(rng, atoms, depth - 1)
    return (left & right, left_truth and right_truth) if kind == 1 else (left | right, left_truth or right_truth)


def test_conditions_combine_in_the_core_as_in_python(robot: Robot) -> None:
    robot.step(20)
    q = robot.state().position
    atoms = [(Measure.position(1) > q[1] - 0.05, True), (Measure.position(2) > q[2] + 0.05, False),
             (Measure.velocity(0) < 1.0, True), (Measure.following_error(3) > 1.0, False),
             (Measure.MOTION_TIME > -1.0, False),   # no motion while holding: no value, never true
             (Measure.drive_state(4) == DriveState.OPERATION_ENABLED, True), (Measure.FORCE_Z > 1e4, False),
             (Measure.effort(5) < 1e4, True)]
    gate = Measure.digital_input(0, 0) == 1   # holds every condition false until all 16 are armed
    rng = np.random.default_rng(7)
    for _ in range(8):   # 8 rounds of the 16 slots
        conditions: list[tuple[Condition, bool]] = []
        while len(conditions) < 16:   # as long as a condition may be with the gate, half of them 6-7 comparisons
            condition, truth = _expression(rng, atoms, 4)
            comparisons = sum(term.op < CONSTANTS["PLEM_TERM_AND"] for term in condition.terms)
            if len(condition.terms) <= 14 and (comparisons >= 6 or len(conditions) % 2):
                conditions.append((gate & condition, truth))
        armed = [(robot.on(condition, Record(), once=True), truth) for condition, truth in conditions]
        slots = [robot.runtime.reactions[handle.token].slot for handle, _ in armed]
        robot.bus.set_digital_inputs(0, 1)
        robot.step(2)
        for (handle, truth), slot in zip(armed, slots, strict=True):
            fired = not robot.runtime.arm[0]["reactions"][slot]["armed"]
            assert fired == truth, robot.runtime.reactions[handle.token].text
            handle.remove()
        robot.bus.set_digital_inputs(0, 0)
        robot.step(2)


def test_the_core_refuses_to_arm_a_condition_it_cannot_evaluate(robot: Robot) -> None:
    token = robot.runtime.write_reaction(Measure.FORCE_X > 1.0, Record())
    slot = robot.runtime.reactions[token].slot
    robot.runtime.arm[0]["reactions"][slot]["term"][0]["index"] = 6   # a seventh wrench component
    with pytest.raises(CommandRejected) as raised:
        robot._send(ArmReaction(slot, CommandHandle("arm a reaction", robot._pump))).wait(5.0)
    assert "cannot be evaluated" in str(raised.value) and f"slot {slot}" in str(raised.value)
    assert robot.runtime.arm[0]["reacting"] == 0


def test_a_payload_given_at_build_is_in_the_core_model_from_the_first_cycle() -> None:
    def built(payload: Payload | None) -> Robot:
        config = Indy7V2()
        config.joint_offsets = [-r for r in RAW_ZERO]
        config.custom_bus = MockBus(6, raw_zero=RAW_ZERO)
        return Robot.builder(config).with_payload(payload).build()

    plain, loaded = built(None), built(Payload(3.0, (0.0, 0.0, 0.1)))
    assert loaded.runtime.arm[0]["model"]["mass"][5] == pytest.approx(plain.runtime.arm[0]["model"]["mass"][5] + 3.0)


def test_until_stops_an_executed_trajectory_too(robot: Robot) -> None:
    start = robot.state().position.copy()
    trajectory = JointTrajectory.from_lists(list(robot.joint_names), [
        {"positions": list(start), "time_from_start": 0.0},
        {"positions": list(start + 0.6), "time_from_start": 4.0}])
    handle = robot.execute_trajectory(trajectory, until=Measure.FORCE_X > 20.0)
    robot.step(500)
    robot.bus.push("link6", force=(40.0, 0.0, 0.0))
    result = handle.wait(10.0)
    robot.bus.release()
    assert result.outcome is TrajectoryOutcome.SUCCEEDED and "until condition" in result.message


def test_the_contact_stop_stops_within_the_quickest_stops_distance(robot: Robot) -> None:
    """Stated distance: the core's quickest jerk-limited stop from the command at the fault (plan_stop), no more."""
    trace = Trace.attach(robot)
    robot.move_joints((robot.state().position + 0.8).tolist(), speed_scale=0.5)
    robot.step(600)
    robot.bus.push("link6", force=(150.0, 0.0, 0.0))
    robot.step(200)
    robot.bus.release()
    robot.step(1500)
    assert robot.mode is Mode.FAULT and "contact" in robot.fault_reason
    modes, commands = trace.modes, trace.commands()
    faulted = modes.index(Mode.FAULT)
    before = commands[faulted - 1]
    assert np.abs(before[1]).max() > 0.1, "the arm was moving when the contact stopped it"
    stop = plan_stop(robot.limits, (before[0], before[1], before[2]))
    travelled = np.abs(commands[-1, 0] - before[0])
    stated = np.abs(stop.final_positions - before[0])
    assert np.all(travelled <= stated + 1e-3)
