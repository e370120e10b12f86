"""The simulated arm driven the way the loop drives a bus: read() and write() once per simulated cycle."""

import re
from functools import cache

import numpy as np
import pytest

from plem.control.kinematics import ArmDynamics
from plem.description.validate import Stage, validate_package
from plem.errors import CommandRejected, ConfigError, PlemError
from plem.fieldbus import BusSetup, DriveState, IBus, MockBus, OperationMode
from plem.fieldbus.mock import start_position

CPR = 2**19 / (2 * np.pi) * 100  # 19-bit encoder behind a 1:100 gear
DT = 0.001
CSP, CST = OperationMode.CYCLIC_SYNC_POSITION, OperationMode.CYCLIC_SYNC_TORQUE


@cache
def urdf(package: str = "indy7_v2_description") -> str:
    return validate_package(package, stage=Stage.LAUNCH).urdf_xml


def setup(dof: int = 6, dt: float = DT) -> BusSetup:
    return BusSetup(tuple(f"joint{i}" for i in range(dof)), (CPR,) * dof, dt)


def make_bus(dof=6, *, dt=DT, package="indy7_v2_description", **options) -> MockBus:
    bus = MockBus(dof, urdf(package) if package else None, **options)
    bus.open(setup(dof, dt))
    bus.read()
    return bus


def cycles(bus: MockBus, n: int) -> None:
    for _ in range(n):
        bus.write()
        bus.read()


def enable(bus: MockBus, mode=CSP) -> None:
    """Targets at the actual position, then three cycles to operation enabled."""
    bus.io.mode[:] = mode
    bus.io.target_position[:] = bus.io.position
    bus.io.velocity_offset[:] = 0
    bus.enable()
    cycles(bus, 3)
    assert all(bus.drive_state(d) is DriveState.OPERATION_ENABLED for d in range(bus.dof))


def command(bus: MockBus, q, v=None) -> None:
    bus.io.target_position[:] = np.rint(np.asarray(q) * CPR).astype(np.int64)
    bus.io.velocity_offset[:] = np.rint(np.zeros(bus.dof) if v is None else np.asarray(v) * CPR).astype(np.int64)


BENT = [0.0, 0.8, 0.0, 0.0, 0.0, 0.0]  # shoulder forward: large gravity torque on joint1


# ---- interface, open, encoders ------------------------------------------------------------------

def test_mock_bus_is_an_ibus_and_refuses_io_before_open():
    bus = MockBus(6)
    assert isinstance(bus, IBus)
    with pytest.raises(PlemError, match="not open"):
        bus.read()
    with pytest.raises(PlemError, match="not open"):
        bus.write()


def test_open_checks_the_joint_count():
    with pytest.raises(ConfigError) as error:
        MockBus(6).open(setup(7))
    assert "6" in error.value.what and "7" in error.value.why and error.value.how


def test_bad_settings_are_config_errors():
    with pytest.raises(ConfigError, match="raw_zero"):
        MockBus(6, raw_zero=[1, 2])
    with pytest.raises(ConfigError, match="effort_limits"):
        MockBus(6, effort_limits=[0, 1, 1, 1, 1, 1])
    with pytest.raises(ConfigError, match="URDF"):
        MockBus(6, "/nonexistent/arm.urdf").open(setup())


def test_raw_counts_round_trip_through_a_calibration_offset():
    raw_zero = [-535768, 12, 0, 7, -3, 1 << 20]
    bus = make_bus(raw_zero=raw_zero, package=None)
    offset = -bus.io.position.copy()  # calibration: minus the raw reading at home
    assert list(bus.io.position) == raw_zero
    q = np.array([0.1, -0.2, 0.3, -1.0, 2.0, -3.0])
    bus.set_positions(q)
    bus.read()
    assert np.array_equal(bus.io.position, np.rint(q * CPR).astype(np.int64) + raw_zero)
    assert np.allclose((bus.io.position + offset) / CPR, q, atol=1 / CPR)


def test_urdf_path_and_effort_limits_from_the_urdf(tmp_path):
    path = tmp_path / "indy7.urdf"
    path.write_text(urdf())
    bus = MockBus(6, path)
    bus.open(setup())
    assert bus.simulates_dynamics
    assert np.allclose(bus.effort_limits, [431.97, 431.97, 197.23, 79.79, 79.79, 79.79])


def test_a_urdf_path_is_read_only_when_a_regular_file_of_sane_size(tmp_path):
    large = tmp_path / "large.urdf"
    large.write_text(urdf().replace("</robot>", f"<!-- {'x' * 17 * 2**20} --></robot>"))
    with pytest.raises(ConfigError, match="File too large") as caught:
        MockBus(6, large).open(setup())
    assert "17.0 MiB" in caught.value.why and "16.0 MiB" in caught.value.what
    with pytest.raises(ConfigError, match="Not a regular file"):
        MockBus(6, tmp_path).open(setup())


# ---- drives -------------------------------------------------------------------------------------

def test_enable_takes_three_cycles_and_disable_one():
    bus = make_bus(package=None)
    assert bus.drive_state(0) is DriveState.SWITCH_ON_DISABLED
    bus.enable()
    seen = []
    for _ in range(3):
        cycles(bus, 1)
        seen.append(bus.drive_state(0))
    assert seen == [DriveState.READY_TO_SWITCH_ON, DriveState.SWITCHED_ON, DriveState.OPERATION_ENABLED]
    assert bus.io.statusword[0] == 0x0237
    bus.disable()
    cycles(bus, 1)
    assert bus.drive_state(0) is DriveState.SWITCH_ON_DISABLED


def test_disabled_drives_hold_the_arm_on_its_brakes():
    bus = make_bus(initial_positions=BENT)
    cycles(bus, 500)
    assert np.array_equal(bus.true_positions, BENT)
    assert not np.any(bus.true_velocities) and not np.any(bus.io.torque)


def test_close_disables_the_drives_and_the_arm_stays_put():
    bus = make_bus(initial_positions=BENT)
    enable(bus)
    bus.close()
    with pytest.raises(PlemError):
        bus.read()
    bus.open(setup())
    bus.read()
    assert all(bus.drive_state(d) is DriveState.SWITCH_ON_DISABLED for d in range(6))
    assert np.allclose(bus.true_positions, BENT, atol=1e-6) and not np.any(bus.true_velocities)


# ---- cyclic-sync position with dynamics ---------------------------------------------------------

def test_csp_holds_the_arm_against_gravity():
    bus = make_bus(initial_positions=BENT)
    enable(bus)
    cycles(bus, 2000)
    assert np.max(np.abs(bus.true_positions - BENT)) < 1e-4
    gravity = ArmDynamics(urdf(), [f"joint{i}" for i in range(6)]).gravity(np.array(BENT), np.zeros(6))
    assert abs(gravity[1]) > 40
    assert np.allclose(bus.io.torque, gravity, atol=0.5)


@pytest.mark.parametrize("dt", [0.00025, 0.001, 0.002])
def test_csp_tracks_a_smooth_motion(dt):
    bus = make_bus(7, dt=dt, package="indyrp2_v2_description")
    enable(bus)
    worst = 0.0
    for k in range(1, int(1.0 / dt)):
        t = (k + 1) * dt  # the target of this cycle is where the joint should be at its end
        # from rest, peak speed 1 rad/s
        q = np.array([1 - np.cos(t), -0.5 * (1 - np.cos(2 * t)), 0, 0.25 * (1 - np.cos(4 * t)), 0, 0, 1 - np.cos(t)])
        v = np.array([np.sin(t), -np.sin(2 * t), 0, np.sin(4 * t), 0, 0, np.sin(t)])
        command(bus, q, v)
        bus.write()
        bus.read()
        worst = max(worst, np.max(np.abs(bus.true_positions - q)))
    assert worst < 1e-4
    assert np.allclose(bus.io.velocity / CPR, v, atol=1e-2)


def test_a_step_command_is_reached_at_the_velocity_limit_without_oscillating():
    bus = make_bus(initial_positions=BENT)
    enable(bus)
    target = np.array(BENT) + [1.0, -0.5, 0.5, 1.0, -1.0, 1.0]
    command(bus, target)
    peak = 0.0
    for _ in range(2000):
        cycles(bus, 1)
        peak = max(peak, np.max(np.abs(bus.true_velocities)))
    assert np.allclose(bus.true_positions, target, atol=1e-5)
    assert peak < 3.3  # the URDF velocity limits are 2.6 to 3.14 rad/s
    assert np.all(np.abs(bus.io.torque) <= bus.effort_limits)


def test_csv_tracks_the_velocity_offset_with_and_without_dynamics():
    for package in ("indy7_v2_description", None):
        bus = make_bus(package=package)
        enable(bus, OperationMode.CYCLIC_SYNC_VELOCITY)
        bus.io.velocity_offset[:] = int(0.5 * CPR)
        cycles(bus, 200)
        assert np.allclose(bus.true_velocities, 0.5, atol=1e-3), package
        assert np.allclose(bus.true_positions, 0.5 * 0.2, atol=0.01), package


def test_effort_limit_caps_the_torque():
    bus = make_bus(initial_positions=BENT, effort_limits=[400, 20, 200, 80, 80, 80])
    enable(bus)
    cycles(bus, 200)
    assert abs(bus.io.torque[1]) == pytest.approx(20)
    assert abs(bus.true_positions[1] - 0.8) > 0.05  # the shoulder sags


def test_a_push_barely_moves_a_stiff_csp_servo():
    bus = make_bus(initial_positions=BENT)
    enable(bus)
    bus.apply_external_torque(0, 50.0)
    cycles(bus, 500)
    assert abs(bus.true_positions[0]) < 1e-3
    assert bus.io.torque[0] == pytest.approx(-50.0, abs=1.0)


# ---- cyclic-sync torque -------------------------------------------------------------------------

def test_cst_gravity_push_and_damping():
    bus = make_bus(initial_positions=BENT, viscous_friction=0.0)
    arm = ArmDynamics(urdf(), [f"joint{i}" for i in range(6)])
    gravity = arm.gravity(np.array(BENT), np.zeros(6))
    bus.io.torque_offset[:] = gravity
    enable(bus, CST)

    def run(n, damping=0.0):
        for _ in range(n):
            q = bus.io.position / CPR
            arm.gravity(q, gravity)
            bus.io.torque_offset[:] = gravity - damping * bus.io.velocity / CPR
            bus.write()
            bus.read()

    run(1000)
    assert np.max(np.abs(bus.true_positions - BENT)) < 1e-4
    bus.apply_external_torque(0, 10.0)
    run(300)
    assert bus.true_velocities[0] > 0.5
    bus.clear_external_torque()
    run(1500, damping=np.array([20.0, 20.0, 5.0, 2.0, 0.5, 0.05]))
    assert np.max(np.abs(bus.true_velocities)) < 1e-3
    assert np.allclose(bus.io.torque, bus.io.torque_offset)


def test_cst_torque_is_clamped_and_joints_stop_at_their_limits():
    bus = make_bus(effort_limits=[5, 400, 200, 80, 80, 80], viscous_friction=0.0)
    enable(bus, CST)
    bus.io.torque_offset[:] = 0
    bus.io.torque_offset[0] = 100.0
    cycles(bus, 3000)
    assert bus.io.torque[0] == pytest.approx(5.0)
    assert bus.true_positions[0] == pytest.approx(3.0543261909900767)
    assert bus.true_velocities[0] == 0.0


# ---- where the simulated arm starts -------------------------------------------------------------------------
def shifted_urdf(lower: float, upper: float) -> str:
    """The Indy7 v2 with joint1's range moved to [lower, upper]."""
    text = urdf()
    start = text.index('<joint name="joint1"')
    end = text.index("</joint>", start)
    joint = text[start:end]
    limit = joint[joint.index("<limit"):joint.index("/>", joint.index("<limit")) + 2]
    moved = re.sub(r'lower="[^"]*"', f'lower="{lower}"', re.sub(r'upper="[^"]*"', f'upper="{upper}"', limit))
    return text[:start] + joint.replace(limit, moved) + text[end:]


def test_the_simulated_arm_starts_inside_every_range():
    home = (0.1, 0.9, -0.2, 0.0, 0.3, 0.0)
    bus = MockBus(6, urdf())
    bus.open(setup())
    assert np.allclose(bus.true_positions, 0.0)                # zero is inside every range: zero
    bus = MockBus(6, shifted_urdf(0.5, 1.5))
    bus.open(BusSetup(setup().joint_names, setup().counts_per_radian, DT, home_position=home))
    assert np.allclose(bus.true_positions, home)               # zero is not, the SRDF's home is
    bus = MockBus(6, shifted_urdf(0.5, 1.5))
    bus.open(BusSetup(setup().joint_names, setup().counts_per_radian, DT, home_position=(0.0,) * 6))
    model = ArmDynamics(shifted_urdf(0.5, 1.5), setup().joint_names)
    lower, upper = (limit[model.model_indices] for limit in (model.model.lowerPositionLimit,
                                                             model.model.upperPositionLimit))
    q = bus.true_positions                                     # neither: the middle of each range
    assert np.allclose(q, (lower + upper) / 2) and np.isclose(q[1], 1.0), q
    bus = MockBus(6, shifted_urdf(0.5, 1.5), initial_positions=[0.0, 0.7, 0, 0, 0, 0])
    bus.open(setup())
    assert np.allclose(bus.true_positions, [0.0, 0.7, 0, 0, 0, 0])   # what the caller asked for, as given


def test_start_position_of_unbounded_and_one_sided_ranges():
    inf = np.inf
    lower, upper = np.array([-inf, 0.2, -inf, 0.1]), np.array([inf, inf, -0.3, 0.5])
    assert np.allclose(start_position(lower, upper, None), [0.0, 0.2, -0.3, 0.3])


# ---- follower mode (no URDF) --------------------------------------------------------------------

def test_follower_converges_to_the_target_and_reports_no_torque():
    bus = make_bus(package=None, follower_time_constant_s=0.005)
    enable(bus)
    target = np.array([0.5, -0.5, 1.0, 0.0, 0.2, -0.2])
    command(bus, target)
    cycles(bus, 10)
    assert np.all(np.abs(bus.true_velocities[target != 0]) > 1)  # still moving, with a lag
    cycles(bus, 100)
    assert np.allclose(bus.true_positions, target, atol=1e-6)
    assert not np.any(bus.io.torque)
    bus.io.mode[:] = CST
    bus.io.torque_offset[:] = 100.0
    cycles(bus, 100)
    assert np.allclose(bus.true_positions, target, atol=1e-6)


def test_follower_velocity_is_the_derivative():
    bus = make_bus(package=None)
    enable(bus)
    before = bus.true_positions
    command(bus, np.full(6, 0.1))
    cycles(bus, 1)
    assert np.allclose(bus.true_velocities, (bus.true_positions - before) / DT)


# ---- fault injection ----------------------------------------------------------------------------

def test_drive_fault_brakes_the_joint_and_needs_reset_and_enable():
    bus = make_bus(initial_positions=BENT)
    enable(bus)
    bus.inject_drive_fault(2, 0x8611)
    bus.read()
    assert bus.drive_state(2) is DriveState.FAULT and bus.io.error_code[2] == 0x8611
    assert bus.drive_state(1) is DriveState.OPERATION_ENABLED
    frozen = bus.true_positions[2]
    command(bus, np.array(BENT) + 0.1)
    cycles(bus, 200)
    assert bus.true_positions[2] == frozen and bus.io.torque[2] == 0
    assert bus.true_positions[1] == pytest.approx(0.9, abs=1e-4)  # the healthy drives go on
    bus.enable()
    cycles(bus, 5)
    assert bus.drive_state(2) is DriveState.FAULT  # enable is ignored while in fault
    bus.fault_reset()
    cycles(bus, 5)
    assert bus.drive_state(2) is DriveState.SWITCH_ON_DISABLED and bus.io.error_code[2] == 0
    bus.enable()
    cycles(bus, 3)
    assert bus.drive_state(2) is DriveState.OPERATION_ENABLED


def fault_every_drive(bus: MockBus) -> None:
    for joint in range(bus.dof):
        bus.inject_drive_fault(joint, 0x7121)


def fault_one_and_disable_the_rest(bus: MockBus) -> None:
    bus.inject_drive_fault(1, 0x2310)
    bus.disable()


def lose_communication_briefly(bus: MockBus) -> None:
    bus.inject_communication_loss(20)  # the drives quick-stop, then switch off when the master is heard again


@pytest.mark.parametrize("fault", [fault_every_drive, fault_one_and_disable_the_rest, lose_communication_briefly])
@pytest.mark.parametrize("bent", [BENT, [0.4, 1.2, -0.9, 0.5, 1.1, 0.3]], ids=["shoulder", "whole_arm"])
def test_drives_down_after_a_fault_hold_the_arm_on_their_brakes(fault, bent):
    """However the drives end up not enabled (in fault, switched off), the brakes hold the bent arm: for three
    simulated seconds nothing moves, velocities and torques read 0."""
    bus = make_bus(initial_positions=bent)
    enable(bus)
    command(bus, bent)
    fault(bus)
    cycles(bus, 30)
    assert not any(bus.drive_state(d) in (DriveState.OPERATION_ENABLED, DriveState.QUICK_STOP_ACTIVE)
                   for d in range(6))
    held = bus.true_positions
    assert np.allclose(held, bent, atol=1e-4)
    counts = bus.io.position.copy()
    for _ in range(3000):
        cycles(bus, 1)
        assert np.array_equal(bus.true_positions, held) and not np.any(bus.true_velocities)
    assert np.array_equal(bus.io.position, counts) and not np.any(bus.io.velocity) and not np.any(bus.io.torque)


def test_persistent_fault_survives_reset_until_cleared():
    bus = make_bus(package=None)
    bus.inject_drive_fault(0, 0x7305, persistent=True)
    bus.read()
    bus.fault_reset()
    cycles(bus, 5)
    assert bus.drive_state(0) is DriveState.FAULT and bus.io.error_code[0] == 0x7305
    bus.clear_drive_fault(0)
    bus.fault_reset()
    cycles(bus, 5)
    assert bus.drive_state(0) is DriveState.SWITCH_ON_DISABLED


def test_communication_loss_quick_stops_and_holds():
    bus = make_bus(initial_positions=BENT, quick_stop_deceleration=10.0)
    enable(bus)
    for k in range(500):  # joint0 accelerates to 1 rad/s
        command(bus, np.array(BENT) + [0.5 * ((k + 1) * DT) ** 2 * 2, 0, 0, 0, 0, 0],
                [2 * (k + 1) * DT, 0, 0, 0, 0, 0])
        cycles(bus, 1)
    assert bus.true_velocities[0] == pytest.approx(1.0, abs=1e-2)
    bus.inject_communication_loss(300)
    answers = []
    for _ in range(300):
        answers.append(bus.read())
        bus.write()
    assert not any(answers)
    assert not bus.status.communication_ok and bus.status.working_counter == 0 and bus.status.lost_frames == 300
    assert abs(bus.true_velocities[0]) < 1e-6
    stopped = bus.true_positions
    assert stopped[0] - 0.25 == pytest.approx(0.05, abs=5e-3)  # v²/2a of the 10 rad/s² ramp
    assert bus.read() and bus.status.communication_ok and bus.status.working_counter == 18
    assert bus.drive_state(0) is DriveState.QUICK_STOP_ACTIVE
    cycles(bus, 2)
    assert bus.drive_state(0) is DriveState.SWITCH_ON_DISABLED  # stays down until enabled again
    assert np.allclose(bus.true_positions, stopped, atol=1e-6)


def test_communication_loss_until_restored():
    bus = make_bus(package=None)
    bus.inject_communication_loss()
    assert not any(bus.read() for _ in range(50))
    bus.restore_communication()
    assert bus.read()


def test_encoder_spike_shows_once():
    bus = make_bus(package=None)
    bus.inject_encoder_spike(3, 5000)
    bus.read()
    assert bus.io.position[3] == 5000
    bus.read()
    assert bus.io.position[3] == 0


def test_stuck_joint_does_not_move_until_freed():
    bus = make_bus()
    enable(bus)
    bus.stick_joint(3)
    stuck_at = bus.true_positions[3]
    command(bus, np.full(6, 0.2))
    cycles(bus, 300)
    assert bus.true_positions[3] == stuck_at and bus.true_velocities[3] == 0.0
    assert bus.true_positions[2] == pytest.approx(0.2, abs=1e-4)
    bus.stick_joint(3, False)
    cycles(bus, 300)
    assert bus.true_positions[3] == pytest.approx(0.2, abs=1e-4)


def test_external_torques_on_every_joint_and_bad_arguments():
    bus = make_bus(viscous_friction=0.0)
    arm = ArmDynamics(urdf(), [f"joint{i}" for i in range(6)])
    bus.io.torque_offset[:] = arm.gravity(np.zeros(6), np.zeros(6))
    enable(bus, CST)
    bus.apply_external_torque([5.0, 0, 0, 0, 0, 0])
    cycles(bus, 100)
    assert bus.true_velocities[0] > 0.1
    for bad in ((9, 1.0), ([1.0, 2.0], None), (0, float("nan")), ([1.0] * 6, 2.0)):
        with pytest.raises(CommandRejected):
            bus.apply_external_torque(*bad)


def test_set_positions_only_while_disabled():
    bus = make_bus(package=None)
    enable(bus)
    with pytest.raises(CommandRejected):
        bus.set_positions(np.zeros(6))
    with pytest.raises(CommandRejected):
        bus.inject_drive_fault(6)
