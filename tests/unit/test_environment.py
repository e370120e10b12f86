from pathlib import Path

import pytest

from plem.core.config.environment import middleware_environment, plem_home
from plem.errors import ConfigError


def test_plem_home_default_and_override(tmp_path: Path):
    assert plem_home({}) == Path("~/.plem").expanduser()
    assert plem_home({"PLEM_HOME": str(tmp_path)}) == tmp_path


def test_domain_id_default_and_valid():
    assert middleware_environment({}).ros_domain_id == 0
    env = middleware_environment({"ROS_DOMAIN_ID": "42"})
    assert env.ros_domain_id == 42 and env.warnings == [] and "ROS_DOMAIN_ID" in env.ros_domain_source


def test_domain_id_outside_spec_range_warns():
    env = middleware_environment({"ROS_DOMAIN_ID": "150"})
    assert env.ros_domain_id == 150 and "0-101" in env.warnings[0]


@pytest.mark.parametrize("value", ["215", "233", "-1", "abc", "4.2"])
def test_domain_id_unusable_is_an_error(value):
    with pytest.raises(ConfigError) as error:
        middleware_environment({"ROS_DOMAIN_ID": value})
    assert "ROS_DOMAIN_ID" in error.value.render()


def test_other_rmw_gets_one_line_warning():
    env = middleware_environment({"RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"})
    assert len(env.warnings) == 1 and "\n" not in env.warnings[0] and "Cyclone" in env.warnings[0]
    assert middleware_environment({"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}).warnings == []
