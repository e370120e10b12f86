"""Reactions, the contact stop, the payload and the simulator's control interface through the process client, against
`plem launch bus:=mock`."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from plem.bridge.client import RobotClient
from plem.control.modes import Mode
from plem.control.reactions import Measure, Record
from plem.errors import CommandRejected
from tests.e2e.launched import Launch, launched_robot, wait_for


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch:
        yield launch


def test_until_and_a_standing_reaction_through_the_client(client: RobotClient) -> None:
    client.set_mode("hold")
    start = client.live_state().command_position.copy()
    events = client.events(timeout=0.0)
    reaction = client.on(Measure.FORCE_X > 20.0, Record())
    move = client.move_joints(start + np.where(start > 0, -0.8, 0.8), speed_scale=0.3,
                              until=Measure.FORCE_X > 20.0)
    assert wait_for(lambda: client.live_state().mode is Mode.TRAJECTORY, 5.0)
    client.simulator.push("link6", force=(40.0, 0.0, 0.0))
    try:
        result = move.wait(10.0)
    finally:
        client.simulator.release()
    assert result.outcome.value == "succeeded" and "until condition: force x > 20 N" in result.message
    reaction.remove()
    fired = [event for event in events if event.kind.value == "reaction"]
    assert fired and "force x > 20 N" in fired[0].reason


def test_an_until_condition_true_from_the_start_is_watched_from_the_motions_first_cycle(client: RobotClient) -> None:
    client.set_mode("hold")
    start = client.live_state().command_position.copy()
    events = client.events(timeout=0.5)
    move = client.move_joints(start + np.where(start > 0, -0.5, 0.5), until=Measure.position(0) > -10.0)
    result = move.wait(10.0)
    assert result.outcome.value == "succeeded" and "until condition: position of 0 > -10 rad" in result.message
    seen = list(events)
    started = [event for event in seen if event.kind.value == "motion_started"]
    fired = [event for event in seen if event.kind.value == "reaction"]
    assert len(started) == 1 and len(fired) == 1
    assert fired[0].cycle == started[0].cycle + 1   # the first measurement after the motion's first command


def test_a_digital_input_set_in_the_simulator_ends_a_motion_through_the_client(client: RobotClient) -> None:
    client.set_mode("hold")
    start = client.live_state().command_position.copy()
    move = client.move_joints(start + np.where(start > 0, -0.8, 0.8), speed_scale=0.3,
                              until=Measure.digital_input("joint5", 16) == 1)
    assert wait_for(lambda: client.live_state().mode is Mode.TRAJECTORY, 5.0)
    client.simulator.set_digital_inputs(5, 1 << 16)
    try:
        result = move.wait(10.0)
    finally:
        client.simulator.set_digital_inputs(5, 0)
    assert result.outcome.value == "succeeded" and "digital input 16 of joint5 == 1" in result.message
    with pytest.raises(CommandRejected, match="not a whole number"):
        client.simulator.set_digital_inputs(5.5, 1)  # type: ignore[arg-type]


def test_a_hard_push_is_a_contact_stop_and_a_reset_holds_where_the_arm_is(client: RobotClient) -> None:
    client.set_mode("hold")
    client.simulator.push("link6", force=(150.0, 0.0, 0.0))
    try:
        assert wait_for(lambda: client.live_state().mode is Mode.FAULT, 5.0)
    finally:
        client.simulator.release()
    fault = client.last_fault()
    assert fault is not None and "contact: the external torque on joint" in fault.reason
    assert wait_for(lambda: np.all(np.abs(client.live_state().velocity) < 1e-3), 10.0)
    before = client.live_state().position.copy()
    assert client.reset_fault() is Mode.HOLD
    after = client.live_state()
    assert np.allclose(after.position, before, atol=1e-3) and np.allclose(after.command_position, after.position,
                                                                           atol=1e-3)


def test_a_payload_mounted_in_the_simulator_is_estimated_within_5_percent(client: RobotClient) -> None:
    client.set_mode("hold")
    bent = client.live_state().command_position.copy()
    bent[[1, 2]] = 0.6, 0.8
    client.move_joints(bent.tolist()).wait(30.0)
    client.simulator.mount_payload(2.0, (0.0, 0.0, 0.05))
    try:
        estimated = client.estimate_payload()
        assert estimated.mass == pytest.approx(2.0, rel=0.05)
        assert np.abs(client.stream_status().external_torque).max() < 0.5   # set: the model explains the load
    finally:
        client.simulator.mount_payload(0.0)
        client.set_payload(0.0)
    with pytest.raises(CommandRejected, match="no such link"):
        client.simulator.push("elbow", force=(1.0, 0.0, 0.0))
