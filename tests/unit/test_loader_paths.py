"""load_config: a missing or OS-rejected path is one ConfigError, with no exception chained to it."""

from pathlib import Path

import pytest

from plem.core.config import load_config
from plem.errors import ConfigError


@pytest.mark.parametrize("path", ["config/robot.yaml", "/" + "a" * 5000, "x" * 300 + "/b.yaml"])
def test_bad_paths_are_one_config_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, path: str):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as error:
        load_config(path, "robot.timeout", int)
    assert error.value.__cause__ is None
    assert error.value.__context__ is None or error.value.__suppress_context__
