import os
import time
from pathlib import Path

import pytest

from plem.core.config import ConfigLoader, load_config, load_config_optional
from plem.errors import ConfigError

DOC = """\
network_interface: enp3s0
rt_priority: 80
joint_offsets: [-535768, 195386, 191634, 34542, 24035, 21232]
robot:
  control:
    timeout: 25
    gain: 1.5
  joints:
    - joint0
    - joint1
"""


@pytest.fixture
def config_file(tmp_path: Path) -> Path:
    path = tmp_path / "config.yaml"
    path.write_text(DOC)
    return path


def test_scalars_arrays_and_nested_keys(config_file: Path):
    assert load_config(config_file, "network_interface", str) == "enp3s0"
    assert load_config(config_file, "rt_priority", int) == 80
    assert load_config(config_file, "joint_offsets", list[int])[0] == -535768
    assert load_config(config_file, "robot.control.timeout", int) == 25
    assert load_config(config_file, "robot.control.gain", float) == 1.5
    assert load_config(config_file, "robot.joints.1", str) == "joint1"
    whole = load_config(config_file)
    assert type(whole) is dict and whole["robot"]["control"] == {"timeout": 25, "gain": 1.5}


def test_int_is_accepted_where_a_float_is_asked(config_file: Path):
    assert load_config(config_file, "rt_priority", float) == 80.0


def test_relative_path_from_working_directory(config_file: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.chdir(config_file.parent)
    assert load_config("config.yaml", "rt_priority", int) == 80


def test_package_relative_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    package = tmp_path / "ws" / "my_robot_description"
    (package / "config").mkdir(parents=True)
    (package / "package.xml").write_text("<package/>")
    (package / "config" / "joint_limits.yaml").write_text("joint_limits:\n  joint0:\n    max_velocity: 2.618\n")
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(tmp_path / "ws"))
    monkeypatch.chdir(tmp_path)
    value = load_config("my_robot_description/config/joint_limits.yaml", "joint_limits.joint0.max_velocity", float)
    assert value == 2.618


def test_optional_and_default(config_file: Path):
    assert load_config_optional(config_file, "missing.key", int) is None
    assert load_config_optional(config_file, "rt_priority", int) == 80
    loader = ConfigLoader.get_instance()
    assert loader.load_or_default(config_file, 5, "retry_count") == 5
    assert loader.load_or_default(config_file, 5, "rt_priority") == 80
    with pytest.raises(ConfigError):
        loader.load_or_default(config_file, 5, "network_interface")  # present but not an int


def test_missing_key_names_file_line_and_neighbours(config_file: Path):
    with pytest.raises(ConfigError) as error:
        load_config(config_file, "robot.control.timeot", int)
    assert f"{config_file}:5" in error.value.why and "timeout" in error.value.why


def test_wrong_type_names_key_and_line(config_file: Path):
    with pytest.raises(ConfigError) as error:
        load_config(config_file, "network_interface", int)
    assert f"{config_file}:1" in error.value.why and "'enp3s0'" in error.value.why


def test_wrong_type_inside_a_list_points_at_the_item(tmp_path: Path):
    path = tmp_path / "c.yaml"
    path.write_text("offsets:\n  - 1\n  - two\n")
    with pytest.raises(ConfigError) as error:
        load_config(path, "offsets", list[int])
    assert f"{path}:3" in error.value.why and "offsets.1" in error.value.why


def test_yaml_syntax_error_has_line_and_column(tmp_path: Path):
    path = tmp_path / "broken.yaml"
    path.write_text("a: 1\nb: [1, 2\nc: 3\n")
    with pytest.raises(ConfigError) as error:
        load_config(path, "a", int)
    assert error.value.summary == "YAML syntax error in broken.yaml"
    assert f"{path}:" in error.value.why


def test_duplicate_keys_are_a_syntax_error(tmp_path: Path):
    path = tmp_path / "dup.yaml"
    path.write_text("a: 1\na: 2\n")
    with pytest.raises(ConfigError, match="YAML syntax error"):
        load_config(path, "a", int)


def test_missing_file_lists_what_was_tried(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as error:
        load_config("nowhere/config.yaml", "a")
    assert str(tmp_path / "nowhere" / "config.yaml") in error.value.why
    assert "no package named 'nowhere'" in error.value.why
    with pytest.raises(ConfigError, match="File not found"):
        load_config(tmp_path / "absent.yaml", "a")


def test_cache_is_reused_until_the_file_changes(config_file: Path):
    loader = ConfigLoader.get_instance()
    first = loader.document(config_file)
    assert loader.document(config_file) is first
    config_file.write_text(DOC.replace("rt_priority: 80", "rt_priority: 81"))
    later = time.time() + 2
    os.utime(config_file, (later, later))
    assert loader.document(config_file) is not first
    assert load_config(config_file, "rt_priority", int) == 81


def test_singleton():
    assert ConfigLoader.get_instance() is ConfigLoader.get_instance()
