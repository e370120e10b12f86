"""The motion slab: a motion written by one mapping is sampled in place through another, and checked."""

from __future__ import annotations

import uuid

import numpy as np
import pytest

from plem.control.limits import ArmLimits
from plem.control.motion import plan_point_to_point
from plem.ipc.motion_slab import MotionSlab, MotionSlabError
from plem.ipc.segment import segment_path

DOF = 6
LIMITS = ArmLimits(tuple(f"j{i}" for i in range(DOF)), np.full(DOF, -3.0), np.full(DOF, 3.0), np.full(DOF, 1.5),
                   np.full(DOF, 4.0), np.full(DOF, 30.0), np.full(DOF, 100.0))


@pytest.fixture
def slab():
    name = f"/test_slab_{uuid.uuid4().hex[:8]}"
    created = MotionSlab.create(name, DOF, slots=2, capacity=64, local_slots=0)
    yield created
    created.remove()
    assert not segment_path(name).exists()


def test_a_motion_written_by_the_service_is_sampled_in_place_by_the_driver(slab):
    motion = plan_point_to_point(LIMITS, (np.zeros(DOF), np.zeros(DOF), np.zeros(DOF)), np.full(DOF, 0.5)).polynomial()
    service = MotionSlab.attach(slab.name)
    try:
        segments = service.write(1, motion)
    finally:
        service.close()
    view = slab.view(1, segments)
    assert np.shares_memory(view.coefficients, slab._values)
    for t in np.linspace(0.0, motion.duration, 50):
        assert all(np.array_equal(a, b) for a, b in zip(view.state_at(t), motion.state_at(t), strict=False))
    assert view.duration == motion.duration and np.array_equal(view.final_positions, motion.final_positions)
    assert np.allclose(view.final_positions, np.full(DOF, 0.5), rtol=0.0, atol=1e-12)


def test_a_start_record_that_does_not_match_the_slot_is_refused(slab):
    motion = plan_point_to_point(LIMITS, (np.zeros(DOF), np.zeros(DOF), np.zeros(DOF)), np.full(DOF, 0.1)).polynomial()
    segments = slab.write(0, motion)
    with pytest.raises(MotionSlabError, match="does not hold the announced motion"):
        slab.view(0, segments + 1)
    with pytest.raises(MotionSlabError, match="no valid slot"):
        slab.view(2, segments)
    with pytest.raises(MotionSlabError, match="no valid slot"):
        slab.view(0, 65)


def test_a_motion_larger_than_a_slot_is_refused(slab):
    motion = plan_point_to_point(LIMITS, (np.zeros(DOF), np.zeros(DOF), np.zeros(DOF)), np.full(DOF, 0.1)).polynomial()
    small = MotionSlab.create(f"/test_slab_{uuid.uuid4().hex[:8]}", DOF, slots=1, capacity=2, local_slots=0)
    try:
        with pytest.raises(MotionSlabError, match="too many segments"):
            small.write(0, motion)
    finally:
        small.remove()
