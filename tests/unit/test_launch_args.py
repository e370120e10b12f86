import pytest

from plem.core.config.launch_args import parse_launch_arguments
from plem.core.config.settings import parse_int, parse_int_list
from plem.errors import MultipleErrors, UsageError
from plem.launch.arguments import DEFAULTS, help_text, parse
from plem.launch.plan import plan_robot

KNOWN = ("rt_priority", "robot_id", "eth_interface")


def test_all_three_spellings_parse():
    tokens = ["rt_priority:=80", "--robot_id", "arm_left", "--eth-interface=enp3s0"]
    assert parse_launch_arguments(tokens, KNOWN) == {"rt_priority": "80", "robot_id": "arm_left",
                                                     "eth_interface": "enp3s0"}


def test_value_may_contain_separator_and_be_empty():
    assert parse_launch_arguments(["robot_id:="], KNOWN) == {"robot_id": ""}
    assert parse_launch_arguments(["robot_id:=a:=b"], KNOWN) == {"robot_id": "a:=b"}


def test_unknown_name_suggests_the_closest():
    with pytest.raises(UsageError) as error:
        parse_launch_arguments(["rt_prio:=3"], KNOWN)
    assert error.value.exit_code == 2
    assert "rt_priority" in error.value.how


def test_unknown_dashed_option_is_reported_as_unknown_not_missing_value():
    with pytest.raises(UsageError, match="Unknown argument 'bogus'"):
        parse_launch_arguments(["--bogus"], KNOWN)


@pytest.mark.parametrize("tokens, message", [
    (["rt_priority"], "Cannot read argument"),
    (["--rt_priority"], "Missing value"),
    (["rt_priority:=1", "--rt_priority", "2"], "given twice"),
])
def test_malformed_command_lines(tokens, message):
    with pytest.raises(UsageError, match=message):
        parse_launch_arguments(tokens, KNOWN)


def test_text_parsers():
    assert parse_int(" 42 ") == 42 and parse_int("-3") == -3
    assert parse_int_list("[1, -2,3]") == [1, -2, 3] and parse_int_list("") == []
    for parser, bad in ((parse_int, "8.5"), (parse_int, "abc"), (parse_int_list, "1,x")):
        with pytest.raises(ValueError):
            parser(bad)


def test_bridge_commands_argument_is_known_and_defaults_to_true():
    assert parse(["bridge_commands:=false"]) == {"bridge_commands": "false"}
    assert DEFAULTS["bridge_commands"] == "true" and "bridge_commands:=" in help_text()


@pytest.mark.parametrize("value, expected", [("", True), ("true", True), ("false", False), ("0", False),
                                             ("no", False)])
def test_plan_carries_bridge_commands(value, expected):
    plan = plan_robot({"bus": "mock", "bridge_commands": value, "record": "false"}, generate=False)
    assert plan.bridge_commands is expected and plan.bridge


def test_invalid_bridge_commands_is_reported_with_the_other_problems():
    with pytest.raises(MultipleErrors) as caught:
        plan_robot({"bus": "mock", "bridge_commands": "readonly", "record": "maybe"}, generate=False)
    rendered = caught.value.render()
    assert "invalid launch argument bridge_commands:=readonly" in rendered
    assert "true or false" in rendered and "bridge_commands:=false" in rendered


def test_words_in_messages_are_escaped_and_cut():
    with pytest.raises(UsageError) as caught:
        parse_launch_arguments(["x\x00" * 100], KNOWN)
    assert "\x00" not in caught.value.render() and "(200 characters)" in caught.value.summary
