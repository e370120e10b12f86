"""The state segment in real POSIX shared memory, across real processes."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import textwrap
import time
import uuid

import numpy as np
import pytest

from plem.control.limits import ArmLimits
from plem.control.modes import Mode
from plem.control.state import ROWS
from plem.ipc.segment import SegmentError, SharedSegment, segment_path
from plem.ipc.state_segment import StateSegment, state_segment_name

JOINTS = tuple(f"joint{i}" for i in range(6))


def limits_for(joints: tuple[str, ...]) -> ArmLimits:
    """Distinct limits per joint, so a reader that mixes up rows or joints notices."""
    base = np.arange(1.0, len(joints) + 1)
    return ArmLimits(joints, -base, base, 2 * base, 3 * base, 4 * base, 5 * base)


LIMITS = limits_for(JOINTS)


@pytest.fixture
def robot_id():
    name = f"test_{uuid.uuid4().hex[:8]}"
    yield name
    SharedSegment.unlink(state_segment_name(name))


def writer_process(robot_id: str) -> subprocess.Popen:
    """A process that owns the segment and publishes a heartbeat every millisecond until killed."""
    code = textwrap.dedent(f"""
        import time, numpy as np, sys
        from plem.ipc.state_segment import StateSegment
        from tests.integration.test_state_segment import LIMITS
        segment = StateSegment.create({robot_id!r}, LIMITS, 1_000_000)
        values = np.zeros((6, 6))
        cycle = 0
        print("ready", flush=True)
        while True:
            cycle += 1
            values[0] = cycle
            segment.block.publish(values, cycle, time.monotonic_ns(), 1, False, True)
            time.sleep(0.001)
    """)
    process = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert process.stdout.readline().strip() == "ready"
    return process


def test_name_permissions_and_round_trip(robot_id):
    segment = StateSegment.create(robot_id, LIMITS, 1_000_000)
    path = segment_path(state_segment_name(robot_id))
    assert path == segment_path(f"/{robot_id}_joint_actual_values")
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    values = np.arange(len(ROWS) * 6, dtype=float).reshape(len(ROWS), 6)
    segment.block.publish(values, 42, time.monotonic_ns(), int(Mode.HOLD), False, True)
    reader = StateSegment.attach(robot_id)
    state = reader.block.read()
    assert reader.header.joint_names == JOINTS and reader.header.cycle_time_ns == 1_000_000
    assert state.cycle == 42 and state.mode is Mode.HOLD and np.array_equal(state.velocity, values[1])
    limits = reader.limits
    assert limits.joint_names == JOINTS
    for row in ("min_position", "max_position", "max_velocity", "max_acceleration", "max_jerk", "max_effort"):
        assert np.array_equal(getattr(limits, row), getattr(LIMITS, row)), row
    reader.close()
    segment.remove()
    assert not path.exists()


def test_reader_in_another_process_sees_the_cycles_advance(robot_id):
    writer = writer_process(robot_id)
    try:
        code = textwrap.dedent(f"""
            import time
            from plem.ipc.state_segment import StateSegment
            segment = StateSegment.attach({robot_id!r}, expected_dof=6)
            first = segment.block.read().cycle
            time.sleep(0.05)
            state = segment.block.read()
            print(first, state.cycle, state.position[0] == state.cycle)
        """)
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=30)
        first, later, consistent = out.stdout.split()
        assert int(later) > int(first) and consistent == "True", out.stderr
    finally:
        writer.kill()
        writer.wait()


def test_second_driver_is_refused_and_a_killed_ones_segment_is_replaced(robot_id):
    writer = writer_process(robot_id)
    try:
        with pytest.raises(SegmentError, match="already has a running RT driver") as caught:
            StateSegment.create(robot_id, LIMITS, 1_000_000)
        assert str(writer.pid) in caught.value.why
    finally:
        writer.send_signal(signal.SIGKILL)
        writer.wait()
    warnings: list[str] = []
    segment = StateSegment.create(robot_id, LIMITS, 1_000_000, warn=warnings.append)
    assert segment.header.owner_pid == os.getpid()
    assert len(warnings) == 1 and "stale" in warnings[0] and str(writer.pid) in warnings[0]
    segment.remove()


def test_dof_mismatch_is_the_ipc_dof_error(robot_id):
    segment = StateSegment.create(robot_id, LIMITS, 1_000_000)
    with pytest.raises(SegmentError, match="IPC DOF mismatch") as caught:
        StateSegment.attach(robot_id, expected_dof=7)
    assert "6 joints" in caught.value.why
    segment.remove()


def test_missing_and_foreign_segments_are_explained(robot_id):
    with pytest.raises(SegmentError, match="does not exist") as caught:
        StateSegment.attach(robot_id)
    assert "plem launch" in caught.value.how
    path = segment_path(state_segment_name(robot_id))
    path.write_bytes(b"not plem" * 1000)
    with pytest.raises(SegmentError, match="unknown layout"):
        StateSegment.attach(robot_id)
    warnings: list[str] = []
    StateSegment.create(robot_id, LIMITS, 1_000_000, warn=warnings.append).remove()
    assert "unreadable" in warnings[0]
