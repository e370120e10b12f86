"""The arm runtime on the simulated arm: modes, motions, limits, faults, calibration and free drive.

The loop is stepped in simulated time (robot.step / waiting on handles), so these tests check behaviour,
never timing.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from plem.control.commands import CommandHandle, StartMotion
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.polynomial import ORDER, PolynomialMotion
from plem.control.trajectory import JointTrajectory, TrajectoryOutcome, TrajectoryPoint, TrajectoryTolerances
from plem.errors import CommandRejected, ConfigError, RobotFault
from plem.fieldbus.bus import DriveState
from plem.fieldbus.mock import MockBus
from plem.ipc.request_bounds import MAX_POINTS
from plem.robot import Indy7V2, IndyRP2V2, Robot, RobotFactory
from plem.robot.profile import RobotProfile

from .robot_fixtures import RAW_ZERO, assert_within_limits, simulated_robot, step_recording

POSE = np.array([0.3, -0.5, 0.8, 0.2, 0.6, -0.4])


@pytest.fixture
def robot():
    robot = simulated_robot()
    yield robot
    robot.shutdown()


@pytest.fixture
def holding(robot):
    assert robot.set_mode("hold") is Mode.HOLD
    return robot


def faults(robot):
    return [e for e in robot.events.recent({EventKind.FAULT})]


# -- building ------------------------------------------------------------------------------------

def test_factory_uses_the_given_bus_and_builder_sets_robot_id():
    robot = RobotFactory.create(Indy7V2(), MockBus(6))
    assert robot.joint_names == tuple(f"joint{i}" for i in range(6))
    robot.shutdown()
    config = Indy7V2()
    config.custom_bus = MockBus(6)
    left = Robot.builder(config).with_robot_id("arm_left").build()
    assert left.robot_id == "arm_left"
    left.shutdown()


def test_bus_with_wrong_dof_is_a_config_error():
    with pytest.raises(ConfigError):
        RobotFactory.create(Indy7V2(), MockBus(7))


def test_invalid_config_is_rejected_before_the_bus_opens():
    config = Indy7V2(rt_priority=99)
    with pytest.raises(ConfigError):
        RobotFactory.create(config, MockBus(6))


# -- calibration ---------------------------------------------------------------------------------

def test_offsets_from_code_make_home_read_zero(robot):
    robot.step(2)
    assert np.allclose(robot.state().position, 0.0, atol=1e-6)


def test_uncalibrated_arm_reads_the_raw_zero_as_an_angle():
    robot = simulated_robot(calibrated=False)
    robot.step(2)
    expected = np.array(RAW_ZERO) / np.array(Indy7V2.MODEL.counts_per_radian())
    assert np.allclose(robot.state().position, expected, atol=1e-6)
    robot.shutdown()


def test_profile_offsets_are_loaded_when_robot_serial_is_set():
    """Calibration procedure: read raw at home, negate, save in a profile; the built robot then reads zero."""
    RobotProfile(robot_serial="PE07TEST0001", joint_offsets=[-r for r in RAW_ZERO]).save(
        RobotProfile.default_path("PE07TEST0001"))
    robot = simulated_robot(Indy7V2(robot_serial="PE07TEST0001"))
    robot.step(2)
    assert np.allclose(robot.state().position, 0.0, atol=1e-6)
    robot.shutdown()


def test_commanded_angles_round_trip_through_counts(holding):
    handle = holding.move_joints(POSE)
    assert handle.wait(20).outcome is TrajectoryOutcome.SUCCEEDED
    assert np.allclose(holding.bus.true_positions, POSE, atol=2e-3)
    assert np.allclose(holding.state().position, holding.bus.true_positions, atol=1e-5)


# -- modes ---------------------------------------------------------------------------------------

def test_enable_seeds_the_command_with_the_measured_position(robot):
    robot.bus.set_positions(POSE)
    robot.step(3)
    robot.set_mode("hold")
    state = robot.state()
    assert np.allclose(state.command_position, state.position, atol=1e-6)
    trace = step_recording(robot, 500)
    assert np.max(np.abs(np.array(trace.position) - POSE)) < 1e-3
    assert not faults(robot)


def test_mode_transitions_are_checked(holding):
    with pytest.raises(CommandRejected, match="TRAJECTORY"):
        holding.set_mode("trajectory")
    with pytest.raises(CommandRejected):
        holding.set_mode("fault")
    with pytest.raises(CommandRejected, match="unknown mode"):
        holding.set_mode("sideways")
    assert holding.set_mode("idle") is Mode.IDLE
    assert holding.set_mode("hold") is Mode.HOLD


def test_motion_needs_enabled_drives(robot):
    with pytest.raises(CommandRejected, match="IDLE"):
        robot.move_joints(POSE)


def test_every_transition_is_an_event_with_a_cause(holding):
    holding.set_mode("idle")
    changes = holding.events.recent({EventKind.MODE_CHANGED})
    assert [(e.previous_mode, e.mode) for e in changes] == [(Mode.IDLE, Mode.HOLD), (Mode.HOLD, Mode.IDLE)]
    assert all(e.cause and e.reason for e in changes)


# -- motions -------------------------------------------------------------------------------------

def test_move_joints_reaches_the_target_within_limits(holding):
    handle = holding.move_joints(POSE)
    trace = step_recording(holding, 20_000, until=lambda: handle.done)
    result = handle.wait(0)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED
    assert np.allclose(trace.position[-1], POSE, atol=2e-3)
    assert_within_limits(holding, trace.commands())
    assert holding.mode is Mode.HOLD


def test_speed_scale_slows_the_motion(holding):
    fast = holding.move_joints(POSE)
    fast_cycles = len(step_recording(holding, 20_000, until=lambda: fast.done).command)
    slow = holding.move_joints(np.zeros(6), speed_scale=0.5)
    slow_cycles = len(step_recording(holding, 40_000, until=lambda: slow.done).command)
    assert slow_cycles == pytest.approx(2 * fast_cycles, rel=0.02)


@pytest.mark.parametrize("target, words", [
    ([0, 0, 3.5, 0, 0, 0], ["joint2", "max_position", "3.5"]),
    ([0, 0, 0, 0, 0, float("nan")], ["NaN"]),
    ([0, 0, 0], ["3 values for 6 joints"]),
])
def test_bad_targets_are_rejected_before_execution(holding, target, words):
    with pytest.raises(CommandRejected) as caught:
        holding.move_joints(target)
    text = caught.value.render()
    assert all(word in text for word in words), text
    assert holding.mode is Mode.HOLD


@pytest.mark.parametrize("scale", [0.0, 1.5, float("inf")])
def test_speed_scale_out_of_range_is_rejected(holding, scale):
    with pytest.raises(CommandRejected, match="speed_scale"):
        holding.move_joints(POSE, speed_scale=scale)


def quintic_trajectory(points: list[tuple[float, list[float]]]) -> JointTrajectory:
    zeros = (0.0,) * 6
    return JointTrajectory(tuple(f"joint{i}" for i in range(6)),
                           tuple(TrajectoryPoint(tuple(q), t, zeros, zeros) for t, q in points))


def test_trajectory_is_followed_and_succeeds(holding):
    trajectory = quintic_trajectory([(2.0, [0.2] * 6), (4.0, [0.4, -0.2, 0.3, 0.0, 0.1, 0.2])])
    handle = holding.execute_trajectory(trajectory)
    trace = step_recording(holding, 10_000, until=lambda: handle.done)
    assert handle.wait(0).outcome is TrajectoryOutcome.SUCCEEDED
    assert_within_limits(holding, trace.commands())
    assert np.allclose(trace.position[-1], [0.4, -0.2, 0.3, 0.0, 0.1, 0.2], atol=2e-3)


def test_trajectory_too_fast_runs_slower_within_the_limits_and_says_how_much(holding):
    handle = holding.execute_trajectory(quintic_trajectory([(0.2, [1.0] * 6)]))
    trace = step_recording(holding, 20_000, until=lambda: handle.done)
    result = handle.wait(0)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED
    assert "slowed to stay within the limits" in result.message and "instead of 0.200 s" in result.message
    assert_within_limits(holding, trace.commands())
    assert np.allclose(trace.position[-1], [1.0] * 6, atol=2e-3)
    started = [e for e in holding.events.recent({EventKind.MOTION_STARTED}) if e.cause == "trajectory"][-1]
    assert "instead of 0.200 s" in started.reason


@pytest.mark.parametrize("shape", ["positions", "cubic"])
def test_positions_only_and_cubic_trajectories_run_within_the_limits(holding, shape):
    positions = [[0.1 * k, -0.05 * k, 0.08 * k, 0.0, 0.05 * k, -0.1 * k] for k in range(1, 6)]
    points = tuple(TrajectoryPoint(tuple(q), 0.5 * k, None if shape == "positions" else
                                   tuple((0.0 if k == 5 else 0.2 * np.sign(v)) for v in q))
                   for k, q in enumerate(positions, start=1))
    handle = holding.execute_trajectory(JointTrajectory(tuple(f"joint{i}" for i in range(6)), points))
    trace = step_recording(holding, 20_000, until=lambda: handle.done)
    result = handle.wait(0)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED, result.message
    assert "smoothed at the points" in result.message
    assert_within_limits(holding, trace.commands())
    assert np.allclose(trace.position[-1], positions[-1], atol=2e-3)


def test_new_motion_preempts_the_running_one_without_a_jump(holding):
    first = holding.move_joints(POSE)
    trace = step_recording(holding, 300)
    second = holding.move_joints(-POSE / 2)
    step_recording(holding, 20_000, trace, until=lambda: second.done)
    assert first.wait(0).outcome is TrajectoryOutcome.PREEMPTED
    assert second.wait(0).outcome is TrajectoryOutcome.SUCCEEDED
    assert_within_limits(holding, trace.commands())
    assert not faults(holding)


def test_trajectory_preempts_a_trajectory_from_its_current_state(holding):
    first = holding.execute_trajectory(quintic_trajectory([(3.0, [0.5] * 6)]))
    trace = step_recording(holding, 1200)
    second = holding.execute_trajectory(quintic_trajectory([(3.0, [-0.2] * 6)]))
    step_recording(holding, 10_000, trace, until=lambda: second.done)
    assert first.wait(0).outcome is TrajectoryOutcome.PREEMPTED
    assert second.wait(0).outcome is TrajectoryOutcome.SUCCEEDED
    assert_within_limits(holding, trace.commands())
    assert np.allclose(trace.position[-1], -0.2, atol=2e-3)


def test_stop_cancels_with_a_smooth_stop_then_holds(holding):
    handle = holding.move_joints(POSE)
    trace = step_recording(holding, 400)
    holding.stop().wait(1)
    step_recording(holding, 5_000, trace, until=lambda: holding.runtime.basis.motion is None)
    assert handle.wait(0).outcome is TrajectoryOutcome.CANCELED
    assert_within_limits(holding, trace.commands())
    assert holding.mode is Mode.HOLD
    assert np.allclose(trace.command[-1][1], 0.0)


# -- faults --------------------------------------------------------------------------------------

def fault_during_motion(robot, inject) -> tuple:
    handle = robot.move_joints(POSE)
    trace = step_recording(robot, 300)
    inject(robot.bus)
    step_recording(robot, 5_000, trace, until=lambda: robot.runtime.basis.motion is None and robot.mode is Mode.FAULT)
    step_recording(robot, 50, trace)
    return handle, trace


def test_drive_fault_is_decoded_aborts_and_stops_smoothly(holding):
    handle, trace = fault_during_motion(holding, lambda bus: bus.inject_drive_fault(2, 0x7121))
    [event] = faults(holding)
    assert event.cause == "drive_fault" and "joint2" in event.reason and "0x7121" in event.reason
    assert "blocked" in event.reason.lower()
    with pytest.raises(RobotFault):
        handle.wait(0)
    assert handle.result.outcome is TrajectoryOutcome.ABORTED
    assert_within_limits(holding, trace.commands())
    assert np.allclose(trace.command[-1][1], 0.0)


def test_fault_needs_reset_and_reset_never_jumps(holding):
    fault_during_motion(holding, lambda bus: bus.inject_drive_fault(0, 0x2310))
    with pytest.raises(CommandRejected, match="FAULT"):
        holding.set_mode("hold")
    with pytest.raises(CommandRejected):
        holding.move_joints(POSE)
    before = holding.state().position
    assert holding.reset_fault() is Mode.HOLD
    state = holding.state()
    assert np.allclose(state.command_position, state.position, atol=1e-6)
    trace = step_recording(holding, 300)
    assert np.max(np.abs(np.array(trace.position) - before)) < 2e-3
    assert holding.events.recent({EventKind.FAULT_CLEARED})


def test_stuck_joint_faults_on_tracking_error(holding):
    handle, _ = fault_during_motion(holding, lambda bus: bus.stick_joint(1))
    [event] = faults(holding)
    assert event.cause == "tracking_error" and "joint1" in event.reason


def test_encoder_spike_faults_naming_the_joint(holding):
    fault_during_motion(holding, lambda bus: bus.inject_encoder_spike(4, 200_000))
    [event] = faults(holding)
    assert event.cause == "encoder_jump" and "joint4" in event.reason


def test_communication_loss_faults_and_reset_waits_for_the_bus(holding):
    fault_during_motion(holding, lambda bus: bus.inject_communication_loss())
    [event] = faults(holding)
    assert event.cause == "communication_lost"
    with pytest.raises(RobotFault, match="cannot be reset"):
        holding.reset_fault()
    holding.bus.restore_communication()
    holding.step(1000)
    assert holding.reset_fault() is Mode.HOLD


def test_in_fault_with_the_drives_down_the_brakes_hold_the_bent_arm(holding):
    """A fault the drives cannot be reset from leaves them switched off in FAULT: the arm, bent so that gravity
    pulls on it, stays where it stopped, encoder for encoder, and reads no velocity."""
    holding.move_joints([0.0, 0.9, -0.6, 0.4, 1.0, 0.2]).wait()
    holding.bus.inject_drive_fault(1, 0x7121, persistent=True)
    holding.step(100)
    assert holding.mode is Mode.FAULT
    with pytest.raises(RobotFault, match="did not enable"):
        holding.reset_fault()
    holding.step(2)
    assert [holding.bus.drive_state(i) for i in range(6)] == [DriveState.SWITCH_ON_DISABLED] + [DriveState.FAULT] + [
        DriveState.SWITCH_ON_DISABLED] * 4
    before = holding.state()
    trace = step_recording(holding, 3000)
    assert holding.mode is Mode.FAULT
    assert np.array_equal(np.array(trace.position), np.tile(before.position, (3000, 1)))
    assert not np.any(np.array(trace.velocity)) and not np.any(holding.bus.true_velocities)


def test_in_fault_an_arm_the_drives_cannot_hold_goes_onto_its_brakes(holding):
    """A faulted arm is held by its enabled drives; pushed beyond what they can hold (here an external torque
    twice their effort limit), it is not left to run away: the drives are disabled, the brakes hold it, and an
    event says why."""
    holding.move_joints([0.0, 0.9, -0.6, 0.4, 1.0, 0.2]).wait()
    holding.runtime.fault("internal_error", "cycle raised RuntimeError('stop here')")
    holding.step(1000)
    assert holding.mode is Mode.FAULT and holding.bus.drive_state(1) is DriveState.OPERATION_ENABLED
    pushed_at = holding.runtime.cycle_count
    holding.bus.apply_external_torque(1, 2.0 * float(holding.bus.effort_limits[1]))
    trace = step_recording(holding, 3000)
    [warning] = holding.events.recent({EventKind.WARNING})
    assert warning.cause == "brakes_engaged" and "could not hold the arm" in warning.reason
    assert "brakes hold" in warning.reason and warning.cycle - pushed_at < 50
    assert all(holding.bus.drive_state(i) is DriveState.SWITCH_ON_DISABLED for i in range(6))
    positions = np.array(trace.position)
    assert np.array_equal(positions[-1000:], np.tile(positions[-1], (1000, 1)))
    assert not np.any(holding.bus.true_velocities)
    holding.bus.clear_external_torque()
    assert holding.reset_fault() is Mode.HOLD
    assert np.allclose(holding.state().command_position, positions[-1])


def test_internal_error_in_a_cycle_faults_instead_of_crashing(holding):
    holding.runtime.fault("internal_error", "cycle raised RuntimeError('boom')")
    [event] = faults(holding)
    assert "boom" in event.reason


# -- free drive ----------------------------------------------------------------------------------

FREE_DRIVE_TOLERANCE = 2e-3  # rad of drift allowed over 2 s under gravity


def test_free_drive_holds_against_gravity_and_follows_a_push(holding):
    pose = np.array([0.0, 0.8, -0.6, 0.0, 0.5, 0.0])
    holding.move_joints(pose).wait(20)
    holding.set_mode("free_drive")
    cycles_per_second = round(1 / holding.runtime.dt)
    trace = step_recording(holding, 2 * cycles_per_second)
    drift = np.max(np.abs(np.array(trace.position) - pose))
    assert drift < FREE_DRIVE_TOLERANCE, drift
    holding.bus.apply_external_torque(0, 5.0)
    step_recording(holding, cycles_per_second // 2, trace)
    assert trace.position[-1][0] > 0.05
    holding.bus.clear_external_torque()
    step_recording(holding, 2 * cycles_per_second, trace)
    assert abs(trace.velocity[-1][0]) < 0.01
    assert not faults(holding)
    assert holding.set_mode("hold") is Mode.HOLD


def test_free_drive_torque_is_gravity_minus_damping_clamped_to_the_effort_limits(holding):
    holding.set_mode("free_drive")
    holding.bus.apply_external_torque(1, 30.0)
    dof, arm = holding.limits.dof, holding.runtime.arm
    damping = holding.runtime.arm["settings"]["damping"][0][:dof]
    for effort in (holding.limits.max_effort, np.full(dof, 2.0)):
        arm["settings"]["max_effort"][0][:dof] = effort
        holding.step(50)
        state = holding.state()
        gravity = holding.dynamics.gravity(state.position, np.zeros(dof))
        expected = np.clip(gravity - damping * state.velocity, -effort, effort)
        assert np.any(state.velocity != 0.0)
        np.testing.assert_allclose(arm["io_torque_offset"][0][:dof], expected, rtol=0, atol=1e-9)
    assert np.any(np.abs(expected) == 2.0), "the smaller limit clamps"


def test_free_drive_needs_standstill_to_leave_to_idle(holding):
    holding.set_mode("free_drive")
    holding.bus.apply_external_torque(0, 5.0)
    holding.step(300)
    with pytest.raises(CommandRejected, match="moves"):
        holding.set_mode("idle")


# -- 7 DOF and the threaded loop -----------------------------------------------------------------

def test_seven_dof_arm_moves_in_a_background_thread():
    config = IndyRP2V2()
    config.custom_bus = MockBus(7)
    robot = Robot.builder(config).with_loop_settings(realtime=False).build()
    with robot:
        robot.set_mode("hold")
        result = robot.move_joints([0.2, -0.2, 0.3, 0.1, -0.1, 0.2, 0.1]).wait(10)
        assert result.outcome is TrajectoryOutcome.SUCCEEDED
        assert robot.timing()["cycles"] > 0
    assert robot.mode is Mode.IDLE
    assert not robot.running


def test_steady_state_cycles_keep_their_buffers_and_do_not_grow_memory(holding):
    import tracemalloc

    holding.execute_trajectory(quintic_trajectory([(8.0, [0.5] * 6)]))
    holding.step(200)
    runtime = holding.runtime
    buffers = [id(a) for a in (runtime.arm, runtime.work, holding.bus.io.target_position)]
    tracemalloc.start()
    try:
        holding.step(100)
        before, _ = tracemalloc.get_traced_memory()
        holding.step(3000)
        after, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert [id(a) for a in (runtime.arm, runtime.work, holding.bus.io.target_position)] == buffers
    assert after - before < 2048, after - before


def test_a_stop_that_names_a_replaced_goal_leaves_the_new_one_running(holding):
    first = holding.move_joints(POSE)
    step_recording(holding, 200)
    second = holding.move_joints(-POSE / 2)
    holding.stop(goal=first).wait(1)                  # a cancel that arrives after the preemption
    step_recording(holding, 20_000, until=lambda: second.done)
    assert first.wait(0).outcome is TrajectoryOutcome.PREEMPTED
    assert second.wait(0).outcome is TrajectoryOutcome.SUCCEEDED


def test_an_unbounded_goal_time_waits_without_breaking_the_cycle(holding):
    handle = holding.move_joints(POSE / 4, tolerances=TrajectoryTolerances(goal=np.full(6, 1e-3),
                                                                            goal_time=math.inf))
    step_recording(holding, 20_000, until=lambda: handle.done)
    assert handle.wait(0).outcome is TrajectoryOutcome.SUCCEEDED
    assert not faults(holding)


def test_a_motion_that_commands_nan_faults_and_stops_from_the_measured_state(holding):
    dof = holding.limits.dof
    coefficients = np.zeros((1, ORDER, dof))
    coefficients[0, 0] = holding.state().command_position
    coefficients[0, 1, 2] = np.nan
    motion = PolynomialMotion(np.array([0.0, 1.0]), coefficients, np.zeros((3, dof)))
    handle = CommandHandle("nan")
    holding.runtime.submit(StartMotion(motion, holding.runtime.basis, None, TrajectoryTolerances(), handle))
    trace = step_recording(holding, 2_000)
    assert [event.cause for event in faults(holding)] == ["invalid_command"]
    assert np.isfinite(np.array(trace.command)).all()
    assert_within_limits(holding, trace.commands())
    with pytest.raises(RobotFault, match="aborted"):
        handle.wait(0)


def test_a_trajectory_of_too_many_points_is_refused_before_any_work(holding):
    points = tuple(TrajectoryPoint(tuple(POSE), 1.0 + i) for i in range(MAX_POINTS + 1))
    with pytest.raises(CommandRejected, match="too many points"):
        holding.execute_trajectory(JointTrajectory(holding.joint_names, points))
