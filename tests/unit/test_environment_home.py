"""PLEM_HOME must be a folder (or not there yet); ROS_DOMAIN_ID errors say what is wrong with the value."""

from pathlib import Path

import pytest

from plem.core.config.environment import middleware_environment, plem_home
from plem.errors import ConfigError


def test_missing_or_folder_home_is_accepted(tmp_path: Path):
    assert plem_home({"PLEM_HOME": str(tmp_path)}) == tmp_path
    assert plem_home({"PLEM_HOME": str(tmp_path / "new")}) == tmp_path / "new"


@pytest.mark.parametrize(("home", "why"), [
    ("{tmp}/file", "it is a regular file"),
    ("/dev/null", "it is a character device"),
    ("{tmp}/file/below", "Not a directory"),
])
def test_home_that_is_not_a_folder_names_plem_home(tmp_path: Path, home: str, why: str):
    (tmp_path / "file").write_text("")
    with pytest.raises(ConfigError) as error:
        plem_home({"PLEM_HOME": home.format(tmp=tmp_path)})
    assert error.value.summary.startswith("PLEM_HOME is not a folder") and why in error.value.why
    assert "export PLEM_HOME=" in error.value.how


def test_negative_domain_id_is_called_negative():
    with pytest.raises(ConfigError) as error:
        middleware_environment({"ROS_DOMAIN_ID": "-1"})
    assert "cannot be negative" in error.value.why and "above" not in error.value.why
