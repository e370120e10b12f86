"""Building simulated robots for runtime tests, and recording what the loop commanded cycle by cycle."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from plem.control.modes import Mode
from plem.fieldbus.mock import MockBus
from plem.robot import Indy7V2, Robot
from plem.robot.config import SerialArmConfig

RAW_ZERO = [-535768, 195386, 191634, 34542, 24035, 21232]


def simulated_robot(config: SerialArmConfig | None = None, bus: MockBus | None = None, *,
                    calibrated: bool = True, **runtime_settings: float) -> Robot:
    """An Indy7 v2 on a MockBus with dynamics whose encoders read RAW_ZERO at home, calibrated to match."""
    config = config or Indy7V2()
    if bus is None:
        bus = MockBus(config.dof, raw_zero=RAW_ZERO[:config.dof])
    if calibrated and not config.robot_serial:
        config.joint_offsets = [-r for r in RAW_ZERO[:config.dof]]
    config.custom_bus = bus
    builder = Robot.builder(config)
    if runtime_settings:
        builder.with_runtime_settings(**runtime_settings)
    return builder.build()


@dataclass
class Trace:
    """Per-cycle copies of the published state of every cycle the robot runs while attached."""

    command: list[np.ndarray] = field(default_factory=list)
    position: list[np.ndarray] = field(default_factory=list)
    velocity: list[np.ndarray] = field(default_factory=list)
    modes: list[Mode] = field(default_factory=list)

    @classmethod
    def attach(cls, robot: Robot) -> Trace:
        """Record after each cycle, including cycles run while waiting on command handles."""
        trace = cls()
        cycle = robot.runtime.cycle

        def recorded_cycle() -> None:
            cycle()
            trace.record(robot)

        robot.runtime.cycle = recorded_cycle
        return trace

    def record(self, robot: Robot) -> None:
        state = robot.state()
        self.command.append(np.vstack([state.command_position, state.command_velocity,
                                       state.command_acceleration]))
        self.position.append(state.position)
        self.velocity.append(state.velocity)
        self.modes.append(state.mode)

    def commands(self) -> np.ndarray:
        """Array (cycles, 3, dof): commanded position, velocity, acceleration."""
        return np.array(self.command)


def step_recording(robot: Robot, cycles: int, trace: Trace | None = None, until=None) -> Trace:
    """Step the robot up to `cycles` cycles (stopping early once `until()`), recording each cycle.

    With `trace` already attached, cycles run by waiting on handles in between are in it too.
    """
    if trace is None:
        trace = Trace.attach(robot)
    for _ in range(cycles):
        robot.step()
        if until is not None and until():
            break
    return trace


def assert_within_limits(robot: Robot, commands: np.ndarray, slack: float = 1e-6) -> None:
    """No commanded position, velocity, acceleration or per-cycle jerk beyond the arm's limits."""
    limits = robot.limits
    dt = robot.runtime.dt
    position, velocity, acceleration = commands[:, 0], commands[:, 1], commands[:, 2]
    assert np.all(position >= limits.min_position - slack) and np.all(position <= limits.max_position + slack)
    assert np.all(np.abs(velocity) <= limits.max_velocity * (1 + slack) + 1e-9), np.abs(velocity).max(axis=0)
    assert np.all(np.abs(acceleration) <= limits.max_acceleration * (1 + slack) + 1e-9)
    jerk = np.abs(np.diff(acceleration, axis=0)) / dt
    assert np.all(jerk <= limits.max_jerk * (1 + slack) + 1e-6), jerk.max(axis=0)
    # the position moves as the velocity says: a cycle that repeats a moving command is a step in velocity
    mismatch = np.abs(np.diff(position, axis=0) - (velocity[1:] + velocity[:-1]) / 2.0 * dt)
    assert np.all(mismatch <= limits.max_acceleration * dt * dt + 1e-9), mismatch.max(axis=0)
