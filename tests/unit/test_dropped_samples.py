"""Why a sample does not decode, in words, and one warning line per endpoint however many samples are dropped."""

from __future__ import annotations

import logging

import pytest

from plem.middleware import samples
from plem.middleware.samples import SampleDrops, undecodable
from plem.middleware.types import library

TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"


def _error(data: bytes) -> Exception:
    with pytest.raises(Exception) as raised:  # noqa: PT011 - whatever the serializer raises is what is described
        library().message(TRAJECTORY).deserialize(data)
    return raised.value


def _good() -> bytes:
    new = library().new
    return new(TRAJECTORY, joint_names=["joint0"], points=[
        new("trajectory_msgs/msg/JointTrajectoryPoint", positions=[0.5])]).serialize()


def test_invalid_utf8_is_named_with_its_byte():
    data = _good().replace(b"joint0", b"join\xff0")
    assert undecodable(_error(data)) == "a string in it is not valid UTF-8 (byte 0xff at 4 of the string)"


@pytest.mark.parametrize("cut", [10, 30, 50])
def test_a_sample_cut_short_says_so(cut: int):
    assert undecodable(_error(_good()[:cut])) == "it ends before its last field (a length or a field is cut short)"


def test_a_flood_gives_one_line_per_period_with_the_count(caplog: pytest.LogCaptureFixture,
                                                          monkeypatch: pytest.MonkeyPatch):
    now = [100.0]
    monkeypatch.setattr(samples.time, "monotonic", lambda: now[0])
    drops = SampleDrops("topic /arm/joint_trajectory")
    with caplog.at_level(logging.WARNING, logger="plem.dds"):
        for _ in range(50):
            drops.drop("too large")
        now[0] += samples.WARNING_PERIOD_S
        drops.drop("too large")
    assert drops.dropped == 51
    assert [record.getMessage() for record in caplog.records] == [
        "the topic /arm/joint_trajectory dropped a sample: too large",
        "the topic /arm/joint_trajectory dropped a sample: too large; 49 more dropped since the last warning"]
