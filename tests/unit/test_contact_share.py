"""The contact stop's threshold from the launch: `contact_share:=`, a share of each joint's effort limit, or off."""

from __future__ import annotations

import math

import pytest

from plem.control.limits import CONTACT_SHARE
from plem.errors import ConfigError
from plem.launch.arguments import DEFAULTS, contact_share, help_text, parse
from plem.launch.plan import plan_robot


def test_the_launch_argument_gives_a_share_or_off():
    assert float(DEFAULTS["contact_share"]) == CONTACT_SHARE and "contact_share:=" in help_text()
    assert contact_share(parse(["contact_share:=0.4"])["contact_share"]) == 0.4
    assert contact_share("1") == 1.0
    assert contact_share(" OFF ") == math.inf


@pytest.mark.parametrize("text", ["0", "-0.2", "1.5", "40%", "0.2,0.3", "", "inf"])
def test_a_bad_share_says_what_to_give(text: str):
    with pytest.raises(ConfigError) as error:
        contact_share(text)
    assert error.value.summary == f"invalid launch argument contact_share:={text}"
    assert "above 0 and at most 1, or off" in error.value.what
    assert "contact_share:=0.4" in error.value.how and "contact_share:=off" in error.value.how


def test_a_launch_refuses_a_bad_share_before_starting_and_gives_a_good_one():
    with pytest.raises(ConfigError) as error:
        plan_robot({"bus": "mock", "contact_share": "2"}, generate=False)
    assert "contact_share:=2" in error.value.render()
    assert plan_robot({"bus": "mock", "contact_share": "off"}, generate=False).contact_share == math.inf
    assert plan_robot({"bus": "mock"}, generate=False).contact_share == CONTACT_SHARE
