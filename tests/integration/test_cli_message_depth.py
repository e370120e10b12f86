"""YAML nested deeper than any message is a usage error of `plem topic pub`, `service call` and `action send_goal`,
not an internal error: the YAML parser recurses once per level."""

from __future__ import annotations

import subprocess
import sys

import pytest

DEPTH = 3000
FLOW_MAPPINGS = "{a: " * DEPTH + "1" + "}" * DEPTH
FLOW_LISTS = "{data: " + "[" * DEPTH + "]" * DEPTH + "}"
#: As deep as one argument of at most 128 KiB (the kernel's limit) can nest block mappings.
BLOCK_MAPPINGS = "\n".join(" " * level + "a:" for level in range(500)) + " 1"


@pytest.mark.parametrize("command", [
    ("topic", "pub", "--once", "/t", "std_msgs/msg/String"),
    ("service", "call", "/s", "controller_manager_msgs/srv/ListControllers"),
    ("action", "send_goal", "/a", "plem_msgs/action/SetMode"),
], ids=["topic pub", "service call", "action send_goal"])
@pytest.mark.parametrize("values", [FLOW_MAPPINGS, FLOW_LISTS, BLOCK_MAPPINGS],
                         ids=["flow mappings", "flow lists", "block mappings"])
def test_yaml_nested_deeper_than_any_message_is_refused_with_what_why_how(command: tuple[str, ...], values: str):
    result = subprocess.run([sys.executable, "-m", "plem.cli", *command, values], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2, result.stderr
    assert "Internal error" not in result.stderr and "Traceback" not in result.stderr, result.stderr
    lines = result.stderr.splitlines()
    assert lines[0].endswith("is nested too deeply"), result.stderr
    assert [line.split(":")[0] for line in lines[1:4]] == ["WHAT", "WHY", "HOW"], result.stderr
