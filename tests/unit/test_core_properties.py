"""The compiled core against references: CiA402 against the plain-Python state machines, dynamics against pinocchio.

Dynamics are checked on every built-in arm, a scaffolded 7-axis arm, and an arm of continuous, prismatic and
skew-axis joints listed out of order, on states hypothesis draws, to 1e-9.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plem.control import compiled
from plem.control.kinematics import compiled_model
from plem.description.scaffold import create_package
from plem.description.validate import Stage, require_valid
from plem.errors import ConfigError
from plem.fieldbus.bus import DriveState
from plem.fieldbus.cia402 import (
    HOLDABLE,
    STATUSWORD,
    PowerSequencer,
    decode_statusword,
    drive_transition,
    next_controlword,
)
from plem.robot.models import MODELS
from tests import core_references as reference

STATES = list(DriveState)
WORDS = st.integers(0, 0xFFFF)
TOLERANCE = 1e-9


def test_every_statusword_decodes_as_the_profile_table_says():
    for word in range(0x10000):
        assert decode_statusword(word) is reference.decode_statusword(word), hex(word)


@pytest.mark.parametrize("state", STATES)
def test_drive_transitions_match_on_every_low_controlword(state):
    for controlword in range(0x100):
        for previous in (0x00, 0x0F, 0x7F, 0x80, 0xFF):
            assert drive_transition(state, controlword, previous) is \
                reference.drive_transition(state, controlword, previous), (state, controlword, previous)


@given(st.sampled_from(STATES), WORDS, WORDS)
def test_drive_transitions_ignore_the_upper_bits_as_the_reference_does(state, controlword, previous):
    assert drive_transition(state, controlword, previous) is reference.drive_transition(state, controlword, previous)


@pytest.mark.parametrize("state", STATES)
def test_next_controlword_matches_for_every_target_and_previous_word(state):
    for target in HOLDABLE:
        for previous in range(0x100):
            assert next_controlword(state, target, previous) == reference.next_controlword(state, target, previous)


def test_canonical_statuswords_come_from_the_core_and_decode_to_their_state():
    assert {state: decode_statusword(word) for state, word in STATUSWORD.items()} == {s: s for s in STATES}


OPERATIONS = st.one_of(
    st.tuples(st.just("request"), st.sampled_from(sorted(HOLDABLE))),
    st.tuples(st.just("request_reset")), st.tuples(st.just("master_lost")),
    st.tuples(st.just("commands"), st.lists(st.sampled_from(STATES), min_size=6, max_size=6)))


@settings(max_examples=200)
@given(st.lists(OPERATIONS, max_size=40))
def test_the_power_sequencer_chooses_the_reference_controlwords(operations):
    core, plain = PowerSequencer(6), reference.PowerSequencer(6)
    for operation, *arguments in operations:
        if operation == "commands":
            assert list(core.commands(*arguments)) == plain.commands(*arguments)
        else:
            getattr(core, operation)(*arguments)
            getattr(plain, operation)(*arguments)


# ---- dynamics ----------------------------------------------------------------------------------------------

MIXED_ARM = """<robot name="mixed">
  <link name="base"/>
  {links}
  <joint name="c0" type="continuous"><parent link="base"/><child link="l0"/>
    <origin xyz="0 0 0.1" rpy="0.1 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="r1" type="revolute"><parent link="l0"/><child link="l1"/>
    <origin xyz="0.05 0 0.3" rpy="0 0.2 0.3"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-2" upper="2" effort="50" velocity="2"/></joint>
  <joint name="p2" type="prismatic"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0.1 0.2"/><axis xyz="1 0 0"/><limit lower="-0.2" upper="0.2" effort="100" velocity="0.5"/></joint>
  <joint name="f3" type="fixed"><parent link="l2"/><child link="flange"/><origin xyz="0 0 0.1"/></joint>
  <joint name="c4" type="continuous"><parent link="flange"/><child link="l4"/>
    <origin xyz="0 0 0.05" rpy="0.3 -0.2 0.1"/><axis xyz="0.3 0.4 0.866"/></joint>
  <joint name="r5" type="revolute"><parent link="l4"/><child link="l5"/>
    <origin xyz="0.02 0.03 0.2"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="20" velocity="3"/></joint>
  <joint name="r6" type="revolute"><parent link="l5"/><child link="l6"/>
    <origin xyz="0 0 0.15"/><axis xyz="1 0 0"/><limit lower="-2" upper="2" effort="10" velocity="3"/></joint>
</robot>"""
LINK = """<link name="{name}"><inertial><origin xyz="{x} 0.01 {z}" rpy="0.1 0.2 0.3"/><mass value="{mass}"/>
  <inertia ixx="{i}" iyy="{j}" izz="{k}" ixy="0.001" ixz="-0.002" iyz="0.0015"/></inertial></link>"""


def mixed_arm_urdf() -> str:
    links = "\n".join(LINK.format(name=name, x=0.01 * n, z=0.05 + 0.01 * n, mass=3.0 - 0.3 * n, i=0.05 - 0.005 * n,
                                  j=0.04 - 0.004 * n, k=0.03 - 0.003 * n)
                      for n, name in enumerate(["l0", "l1", "l2", "flange", "l4", "l5", "l6"]))
    return MIXED_ARM.format(links=links)


def _arm(urdf_xml: str, order: list[int] | None = None) -> tuple[pin.Model, list[str]]:
    model = pin.buildModelFromXML(urdf_xml)
    names = [model.names[i] for i in range(1, model.njoints)]
    return model, [names[i] for i in order] if order else names


@pytest.fixture(scope="module")
def arms(tmp_path_factory) -> dict[str, tuple[pin.Model, list[str]]]:
    arms = {package: _arm(require_valid(package, stage=Stage.STARTUP).urdf_xml or "") for package in
            (preset.MODEL.description_package for preset in MODELS.values())}
    scaffolded = create_package(tmp_path_factory.mktemp("packages"), "seven", 7).root
    arms["scaffolded 7-axis"] = _arm(require_valid(str(scaffolded), stage=Stage.STARTUP).urdf_xml or "")
    arms["continuous, prismatic, skew, out of order"] = _arm(mixed_arm_urdf(), [3, 0, 5, 1, 4, 2])
    return arms


def _pinocchio_q(model: pin.Model, names: list[str], positions: np.ndarray) -> np.ndarray:
    """pinocchio's configuration of arm positions: a continuous joint carries (cos, sin) of its angle."""
    q = np.empty(model.nq)
    for name, value in zip(names, positions, strict=True):
        joint = model.joints[model.getJointId(name)]
        q[joint.idx_q:joint.idx_q + joint.nq] = (np.cos(value), np.sin(value)) if joint.nq == 2 else (value,)
    return q


def _model_order(model: pin.Model, names: list[str]) -> np.ndarray:
    return np.array([model.joints[model.getJointId(name)].idx_v for name in names])


VALUES = st.lists(st.floats(-3.0, 3.0), min_size=21, max_size=21)


@settings(max_examples=60, deadline=None)
@given(values=VALUES)
def test_inverse_and_forward_dynamics_and_gravity_match_pinocchio(arms, values):
    for arm, (model, names) in arms.items():
        dof = len(names)
        structure = compiled_model(model, names)
        data = model.createData()
        q, v, a = (np.array(values[k * 7:k * 7 + dof]) for k in range(3))
        a *= 3.0
        index = _model_order(model, names)
        pq = _pinocchio_q(model, names, q)
        pv, pa = np.empty(dof), np.empty(dof)
        pv[index], pa[index] = v, a
        out = np.zeros(dof)
        compiled.core.inverse_dynamics(structure, q, v, a, out)
        tau = pin.rnea(model, data, pq, pv, pa)[index]
        np.testing.assert_allclose(out, tau, rtol=0, atol=TOLERANCE, err_msg=f"{arm}: inverse dynamics")
        compiled.core.forward_dynamics(structure, q, v, tau, out)
        np.testing.assert_allclose(out, a, rtol=0, atol=TOLERANCE, err_msg=f"{arm}: forward dynamics")
        compiled.core.forward_dynamics(structure, q, v, np.zeros(dof), out)
        free = pin.aba(model, data, pq, pv, np.zeros(dof))[index]
        np.testing.assert_allclose(out, free, rtol=0, atol=TOLERANCE, err_msg=f"{arm}: free fall")
        compiled.core.gravity(structure, q, out)
        gravity = pin.computeGeneralizedGravity(model, data, pq)[index]
        np.testing.assert_allclose(out, gravity, rtol=0, atol=TOLERANCE, err_msg=f"{arm}: gravity")


def test_a_model_with_a_joint_outside_the_arm_is_refused(arms):
    model, names = arms["scaffolded 7-axis"]
    with pytest.raises(ConfigError, match="not one of the arm joints"):
        compiled_model(model, names[:-1] + ["elsewhere"])


def test_the_core_refuses_buffers_too_small_for_its_structures():
    with pytest.raises(ValueError, match="at least"):
        compiled.core.gravity(bytearray(16), np.zeros(6), np.zeros(6))
    structure = compiled.new(compiled.MODEL)
    structure["dof"] = 6
    with pytest.raises(ValueError, match="at least 48 bytes"):
        compiled.core.gravity(structure, np.zeros(3), np.zeros(6))
    structure["dof"] = compiled.MAX_JOINTS + 1
    with pytest.raises(ValueError, match="dof"):
        compiled.core.gravity(structure, np.zeros(32), np.zeros(32))
