"""Streaming joint targets into the compiled core: the follower keeps every limit whatever the samples do."""

from __future__ import annotations

import numpy as np
import pytest

from plem.control.compiled import core
from plem.control.modes import Mode
from plem.control.trajectory import TrajectoryOutcome
from plem.errors import CommandRejected
from plem.robot import Robot
from tests.integration.robot_fixtures import Trace, assert_within_limits, simulated_robot

#: One sample every 4 cycles: 250 Hz on the 1 kHz loop.
SAMPLE_CYCLES = 4


@pytest.fixture
def robot() -> Robot:
    robot = simulated_robot()
    robot.set_mode("hold")
    return robot


def test_a_250_hz_stream_with_jumps_and_gaps_keeps_every_limit_and_reaches_its_target(robot: Robot) -> None:
    trace = Trace.attach(robot)
    start = robot.state().position.copy()
    target = start.copy()
    for k in range(300):
        target = start.copy()
        target[0] += 0.3 * min(k * 0.004, 1.0)
        target[1] += 0.1 * np.sin(k * 0.012)
        if k >= 100:
            target[2] += 0.5                     # a jump of half a radian
        if not 150 <= k < 160 and k % 7:         # a 40 ms gap, and every seventh sample lost
            robot.servo_joints(target)
        robot.step(SAMPLE_CYCLES)
    for _ in range(500):   # the last target, held: the arm settles on it
        robot.servo_joints(target)
        robot.step(SAMPLE_CYCLES)
    status = robot.stream_status()
    assert status.state == "following" and status.used_count > 0
    assert robot.mode is Mode.TRAJECTORY and robot.fault_reason == ""
    assert np.allclose(robot.state().command_position, target, atol=1e-6)
    robot.step(500)   # no more samples: the stream times out, the arm is at rest and it ends
    assert robot.mode is Mode.HOLD and robot.fault_reason == ""
    assert_within_limits(robot, trace.commands())


def speed_up(robot: Robot, joint: int, samples: int) -> None:
    """Stream 1 rad/s on one joint, a sample every SAMPLE_CYCLES, until the command moves at it."""
    velocities = np.zeros(robot.limits.dof)
    velocities[joint] = 1.0
    for _ in range(samples):
        robot.speed_joints(velocities)
        robot.step(SAMPLE_CYCLES)
    assert robot.state().command_velocity[joint] == pytest.approx(1.0, abs=1e-9)


def test_a_stream_that_stops_arriving_brings_the_arm_to_rest_and_ends(robot: Robot) -> None:
    trace = Trace.attach(robot)
    speed_up(robot, 0, samples=200)
    _, handle, _ = robot._stream
    result = handle.wait(5.0)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED and "no sample for 0.1 s" in result.message
    assert robot.mode is Mode.HOLD
    assert np.all(robot.state().command_velocity == 0.0)
    assert_within_limits(robot, trace.commands())


def test_stop_brings_a_fast_stream_to_rest_within_every_limit_without_a_contact(robot: Robot) -> None:
    """The stop takes the next step of its own plan in the cycle it starts: a cycle that kept the moving command
    would be a step in velocity, which the drives' stiff servo turns into an effort the contact stop catches."""
    trace = Trace.attach(robot)
    speed_up(robot, 1, samples=150)
    robot.stop().wait(1.0)
    robot.step(1000)
    assert robot.mode is Mode.HOLD and robot.fault_reason == ""
    assert np.all(robot.state().command_velocity == 0.0)
    assert_within_limits(robot, trace.commands())


def test_jog_moves_one_joint_and_a_planned_motion_waits_for_the_stream_to_end(robot: Robot) -> None:
    start = robot.state().position.copy()
    for _ in range(50):
        robot.jog("joint1", -0.5)
        robot.step(SAMPLE_CYCLES)
    moved = robot.state().command_position - start
    assert moved[1] < -0.02 and np.all(moved[[0, 2, 3, 4, 5]] == 0.0)
    handle = robot.move_joints(start)   # waits until the stream came to rest and ended, then plans
    handle.wait(30.0)
    assert np.allclose(robot.state().command_position, start, atol=1e-9)


@pytest.mark.parametrize(("call", "words"), [
    (lambda r: r.servo_joints([0.0] * 5), "wrong number of positions"),
    (lambda r: r.servo_joints([float("nan")] * 6), "positions must be finite"),
    (lambda r: r.speed_joints([100.0, 0, 0, 0, 0, 0]), "above its joint's limit"),
    (lambda r: r.jog("elbow", 0.1), "no such joint"),
    (lambda r: r.servo_joints([0.0] * 6, timeout=60.0), "timeout is out of range"),
])
def test_bad_stream_input_is_refused_with_what_why_how(robot: Robot, call, words: str) -> None:
    with pytest.raises(CommandRejected) as raised:
        call(robot)
    assert words in str(raised.value) and "HOW" in str(raised.value)


def test_the_follower_settles_on_a_step_without_buzzing_and_stops_before_a_position_limit() -> None:
    state = np.zeros(3)
    trail = []
    for _ in range(3000):
        core.follow(state, 1.0, 0.0, 1.0, 2.0, 10.0, 200.0, -0.5, 0.8, 0.001)
        trail.append(state.copy())
    trail_ = np.array(trail)
    assert trail_[-1] == pytest.approx([0.8, 0.0, 0.0], abs=1e-9)   # the target past the limit: the limit
    assert trail_[:, 0].max() <= 0.8
    assert np.all(np.abs(np.diff(trail_[:, 2])) <= 200.0 * 0.001 * (1 + 1e-9))
    assert np.all(np.abs(trail_[:, 1]) <= 2.0) and np.all(np.abs(trail_[:, 2]) <= 10.0)


def test_the_speed_override_keeps_the_path_and_every_limit_through_1_03_0_1(robot: Robot) -> None:
    trace = Trace.attach(robot)
    times: list[float] = []
    recorded = robot.runtime.cycle

    def with_time() -> None:
        recorded()
        times.append(float(robot.runtime.arm[0]["override"]["time"]))

    robot.runtime.cycle = with_time
    start = robot.state().position.copy()
    target = start + np.array([2.5, -0.6, 0.7, 0.5, -0.4, 0.3])
    handle = robot.move_joints(target, speed_scale=0.5)
    motion = robot.runtime.basis.motion
    robot.step(300)
    for factor in (0.3, 0.0):
        robot.set_speed_override(factor)
        for _ in range(5000):
            if robot.speed_override == factor:
                break
            robot.step()
        assert robot.speed_override == factor and robot.mode is Mode.TRAJECTORY
    robot.step(300)
    paused = robot.state()   # stopped on its path, the motion still running
    assert robot.mode is Mode.TRAJECTORY and robot.speed_override == 0.0
    assert np.all(paused.command_velocity == 0.0) and np.all(paused.command_acceleration == 0.0)
    assert not np.allclose(paused.command_position, target, atol=1e-3)
    robot.set_speed_override(1.0)
    handle.wait(30.0)
    commands = trace.commands()
    assert_within_limits(robot, commands)
    assert motion is not None and robot.mode is Mode.HOLD and robot.fault_reason == ""
    # every commanded position is the planned path's at the motion's own time: the path is unchanged
    path = np.array([motion.state_at(t)[0] for t in times[-len(commands):]])
    moving = np.array([m is Mode.TRAJECTORY for m in trace.modes])
    assert np.max(np.abs(commands[moving, 0] - path[moving])) < 1e-6
    assert np.allclose(robot.state().command_position, target, atol=1e-9)


def test_random_speed_override_changes_on_random_motions_never_break_a_limit(robot: Robot) -> None:
    rng = np.random.default_rng(32)
    trace = Trace.attach(robot)
    limits = robot.limits
    low, high = limits.min_position * 0.8, limits.max_position * 0.8
    for _ in range(8):
        handle = robot.move_joints(rng.uniform(low, high), speed_scale=float(rng.uniform(0.3, 1.0)))
        while not handle.done:
            robot._request_speed_override(float(rng.choice([0.0, 0.2, 0.5, 0.8, 1.0])))
            robot.step(int(rng.integers(50, 600)))
        handle.wait(0)
        robot._request_speed_override(1.0)
        assert robot.fault_reason == ""
    assert_within_limits(robot, trace.commands())
