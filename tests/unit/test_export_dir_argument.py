"""`export_dir:=`: the launch checks the dataset named before anything starts, without touching it."""

from __future__ import annotations

from typing import Any

import pytest

from plem.errors import ConfigError
from plem.launch.arguments import DEFAULTS, export_dir, help_text
from plem.launch.plan import plan_robot


def test_export_dir_is_a_launch_argument_without_default():
    assert DEFAULTS["export_dir"] == "" and "export_dir:=" in help_text()
    assert export_dir("", True) is None and export_dir("/data/fleet", True) == "/data/fleet"
    assert export_dir("s3://fleet/bags", True) == "s3://fleet/bags"


@pytest.mark.parametrize(("text", "record", "why"), [("s3://", True, "nothing between s3:// and the next /"),
                                                      ("/data/fleet", False, "record:=false")])
def test_a_bad_export_dir_says_what_to_give(text: str, record: bool, why: str):
    with pytest.raises(ConfigError) as error:
        export_dir(text, record)
    assert error.value.summary == f"invalid launch argument export_dir:={text}" and error.value.why == why


def test_an_s3_export_dir_without_s3fs_names_the_extra(monkeypatch: pytest.MonkeyPatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *rest: None if name == "s3fs" else real(name, *rest))
    with pytest.raises(ConfigError) as error:
        export_dir("s3://fleet/bags", True)
    assert error.value.how == "pip install 'plem[s3]'"


def test_the_launch_refuses_a_bad_export_dir_before_starting():
    arguments: dict[str, Any] = {"bus": "mock", "export_dir": "s3:///x"}
    with pytest.raises(ConfigError) as error:
        plan_robot(arguments, generate=False)
    assert "export_dir:=s3:///x" in error.value.render()
    assert plan_robot({"bus": "mock", "export_dir": "/tmp/fleet"}, generate=False).arguments["export_dir"] == \
        "/tmp/fleet"
