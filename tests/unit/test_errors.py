import pytest

from plem.errors import ConfigError, MultipleErrors, PlemError, UsageError, raise_collected


def test_render_has_four_labelled_lines():
    error = ConfigError("Bad thing", what="expected", why="found", how="fix it")
    assert error.render().splitlines() == ["ERROR: Bad thing", "WHAT: expected", "WHY: found", "HOW: fix it"]
    assert str(error) == error.render()
    assert error.exit_code == 1


def test_multiline_fields_are_indented_under_their_label():
    error = PlemError("s", what="a\nb", why="c", how="d")
    assert "WHAT: a\n      b" in error.render()


def test_usage_error_exits_2_and_group_takes_the_worst_code():
    usage = UsageError("u", what="w", why="y", how="h")
    group = MultipleErrors([ConfigError("c", what="w", why="y", how="h"), usage], "here")
    assert usage.exit_code == 2
    assert group.exit_code == 2
    assert group.summary == "2 problems in here"
    rendered = group.render()
    assert rendered.count("ERROR:") == 3 and "ERROR: u" in rendered and "ERROR: c" in rendered
    assert [e["summary"] for e in group.to_dict()["errors"]] == ["c", "u"]


def test_raise_collected_raises_nothing_one_or_all():
    raise_collected([])
    one = ConfigError("one", what="w", why="y", how="h")
    with pytest.raises(ConfigError) as single:
        raise_collected([one])
    assert single.value is one
    with pytest.raises(MultipleErrors) as many:
        raise_collected([one, one])
    assert len(many.value.errors) == 2
