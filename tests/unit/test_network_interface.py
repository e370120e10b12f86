from pathlib import Path

import pytest

from plem.errors import ConfigError
from plem.fieldbus import available_interfaces, check_network_interface


def test_loopback_is_refused_on_this_machine():
    if "lo" not in available_interfaces():
        pytest.skip("this machine has no 'lo' interface in /sys/class/net")
    with pytest.raises(ConfigError, match="loopback"):
        check_network_interface("lo")


def test_missing_interface_message_lists_what_exists():
    with pytest.raises(ConfigError) as error:
        check_network_interface("nosuch0")
    assert error.value.summary == "Network interface does not exist: nosuch0"
    assert "ip link show" in error.value.how


def _fake_sysfs(tmp_path: Path) -> Path:
    net = tmp_path / "net"
    (net / "wlan0" / "wireless").mkdir(parents=True)
    (net / "eth0").mkdir()
    (net / "eth0" / "type").write_text("1\n")
    (net / "eth0" / "flags").write_text("0x1003\n")
    return net


def test_wireless_is_refused_and_wired_passes(tmp_path: Path):
    net = _fake_sysfs(tmp_path)
    with pytest.raises(ConfigError, match="wireless"):
        check_network_interface("wlan0", net)
    check_network_interface("eth0", net)
