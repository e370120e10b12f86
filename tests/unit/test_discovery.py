"""Domain, discovery and security settings from the ROS 2 environment variables, and the Cyclone DDS XML they make."""

from __future__ import annotations

import uuid
from pathlib import Path

import pytest
from lxml import etree

from plem.errors import ConfigError
from plem.ipc.segment import SHM_DIRECTORY
from plem.middleware.discovery import MAX_DOMAIN_ID, RANGES, DiscoverySettings
from plem.middleware.node import Node
from plem.middleware.qos import DEFAULT
from tests.conftest import fresh_domain
from tests.e2e.cli import run_plem

from_env = DiscoverySettings.from_environment


def plem_xml(settings: DiscoverySettings) -> etree._Element:
    """plem's own fragment (the first of the comma-separated configuration), parsed."""
    config = settings.cyclone_config()
    assert config.startswith("<CycloneDDS>")
    return etree.fromstring(config.split(",", 1)[0])


def test_defaults() -> None:
    settings = from_env({})
    assert settings == DiscoverySettings(0, "SUBNET", (), "")
    assert settings.describe() == "ROS_DOMAIN_ID=0, discovery subnet"


def test_reads_os_environ_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", "17")
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")
    assert from_env() == DiscoverySettings(17, "OFF")


@pytest.mark.parametrize(("text", "domain"), [("42", 42), (" 42 ", 42), ("0", 0), ("", 0), ("  ", 0),
                                              (str(MAX_DOMAIN_ID), 232)])
def test_domain_id(text: str, domain: int) -> None:
    assert from_env({"ROS_DOMAIN_ID": text}).domain_id == domain


@pytest.mark.parametrize("text", ["abc", "-1", "233", "4.2", "1e3", "0x10"])
def test_invalid_domain_id(text: str) -> None:
    with pytest.raises(ConfigError) as caught:
        from_env({"ROS_DOMAIN_ID": text})
    rendered = caught.value.render()
    assert rendered.startswith("ERROR: ")
    assert all(f"\n{label}: " in rendered for label in ("WHAT", "WHY", "HOW"))
    assert repr(text) in rendered
    assert "232" in caught.value.what


@pytest.mark.parametrize(("text", "expected"), [
    ("SUBNET", "SUBNET"), ("LOCALHOST", "LOCALHOST"), ("OFF", "OFF"), ("SYSTEM_DEFAULT", "SYSTEM_DEFAULT"),
    ("", "SUBNET"),
])
def test_discovery_range(text: str, expected: str) -> None:
    assert from_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": text}).discovery_range == expected


def assert_explained(error: ConfigError, variable: str, value: str, allowed: tuple[str, ...]) -> None:
    """The error names the variable, the value given and every allowed value, in the WHAT/WHY/HOW form."""
    rendered = error.render()
    assert rendered.startswith("ERROR: ")
    assert all(f"\n{label}: " in rendered for label in ("WHAT", "WHY", "HOW"))
    assert variable in error.summary and repr(value) in rendered
    assert all(name in error.what for name in allowed)
    assert variable in error.how


@pytest.mark.parametrize("text", ["LAN", "local", "SUBNETS", "0", "LOCAL HOST", "localhost", "Off", " OFF",
                                  "system_default"])
def test_invalid_discovery_range(text: str) -> None:
    """Jazzy reads the exact upper-case names only (anything else it replaces by LOCALHOST): plem refuses."""
    with pytest.raises(ConfigError) as caught:
        from_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": text})
    assert_explained(caught.value, "ROS_AUTOMATIC_DISCOVERY_RANGE", text, RANGES)


def test_localhost_only_means_localhost_without_static_peers(caplog: pytest.LogCaptureFixture) -> None:
    settings = from_env({"ROS_LOCALHOST_ONLY": "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
                         "ROS_STATIC_PEERS": "10.0.0.2"})
    assert (settings.discovery_range, settings.static_peers) == ("LOCALHOST", ())
    peers = [peer.get("address") for peer in plem_xml(settings).iter("Peer")]
    assert peers == ["localhost"]
    assert "ROS_LOCALHOST_ONLY is deprecated" in caplog.text
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE and ROS_STATIC_PEERS are ignored" in caplog.text
    assert from_env({"ROS_LOCALHOST_ONLY": "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}).discovery_range == "LOCALHOST"


def test_localhost_only_zero_changes_nothing_but_warns(caplog: pytest.LogCaptureFixture) -> None:
    settings = from_env({"ROS_LOCALHOST_ONLY": "0", "ROS_STATIC_PEERS": "10.0.0.2"})
    assert (settings.discovery_range, settings.static_peers) == ("SUBNET", ("10.0.0.2",))
    assert "ROS_LOCALHOST_ONLY is deprecated" in caplog.text and "it changes nothing" in caplog.text


def test_no_warning_without_deprecated_variables(caplog: pytest.LogCaptureFixture) -> None:
    from_env({"ROS_LOCALHOST_ONLY": "", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "127.0.0.1"})
    assert caplog.text == ""


@pytest.mark.parametrize("text", ["true", "yes", "10", "2", " 1", "on"])
def test_invalid_localhost_only(text: str) -> None:
    """Jazzy reads only a leading '1' (so 'true' would mean off there): plem takes 1 or 0."""
    with pytest.raises(ConfigError) as caught:
        from_env({"ROS_LOCALHOST_ONLY": text})
    assert_explained(caught.value, "ROS_LOCALHOST_ONLY", text, ("1", "0"))


def test_static_peers_in_config() -> None:
    settings = from_env({"ROS_STATIC_PEERS": " localhost:7410 ; ;192.168.1.7;udp/10.0.0.3;"})
    assert settings.static_peers == ("localhost:7410", "192.168.1.7", "udp/10.0.0.3")
    assert [peer.get("address") for peer in plem_xml(settings).iter("Peer")] == list(settings.static_peers)
    assert "static peers localhost:7410, 192.168.1.7, udp/10.0.0.3" in settings.describe()
    local = from_env({"ROS_STATIC_PEERS": "127.0.0.1;10.1.2.3", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    assert [peer.get("address") for peer in plem_xml(local).iter("Peer")] == ["localhost", "127.0.0.1", "10.1.2.3"]


@pytest.mark.parametrize("discovery_range", ["OFF", "SYSTEM_DEFAULT"])
def test_static_peers_ignored_where_jazzy_ignores_them(discovery_range: str, caplog: pytest.LogCaptureFixture) -> None:
    settings = from_env({"ROS_STATIC_PEERS": "10.0.0.2", "ROS_AUTOMATIC_DISCOVERY_RANGE": discovery_range})
    assert settings.static_peers == ()
    assert "10.0.0.2" not in settings.cyclone_config()
    assert f"ROS_STATIC_PEERS is ignored: ROS_AUTOMATIC_DISCOVERY_RANGE={discovery_range}" in caplog.text


@pytest.mark.parametrize("peer", [
    "nonexistent.invalid", "a b", "[::1]", "::1", "127.0.0.1:0", "127.0.0.1:", "127.0.0.1:70000", "0", "0.0.0.0",
    "host_with_underscore", "x" * 300, '"/><Peer address="10.0.0.1', "tcp/10.0.0.1",
])
def test_unusable_static_peer(peer: str) -> None:
    """Each of these makes Cyclone DDS abort the process (or breaks the XML): plem stops first, with the reason."""
    with pytest.raises(ConfigError) as caught:
        from_env({"ROS_STATIC_PEERS": f"127.0.0.1;{peer}"})
    assert_explained(caught.value, "ROS_STATIC_PEERS", peer, ("host names", "IPv4", ":PORT", "';'"))


@pytest.mark.parametrize("text", ["", "false", "FALSE", "0"])
def test_security_off(text: str) -> None:
    environ = {"ROS_SECURITY_ENABLE": text, "ROS_SECURITY_STRATEGY": "Enforce", "ROS_SECURITY_KEYSTORE": "/keys"}
    assert from_env(environ) == DiscoverySettings()


@pytest.mark.parametrize("text", ["true", "True", "1", "yes"])
def test_security_is_refused(text: str) -> None:
    """The cyclonedds wheel has no DDS Security: asking for SROS2 is an error, never a silently open robot."""
    with pytest.raises(ConfigError) as caught:
        from_env({"ROS_SECURITY_ENABLE": text, "ROS_SECURITY_STRATEGY": "Permissive"})
    assert_explained(caught.value, "ROS_SECURITY_ENABLE", text, ("unset", "0", "false"))
    assert "DDS Security" in caught.value.why and "libdds_security" in caught.value.why
    assert "bridge_commands:=false" in caught.value.how


def test_user_config_comes_after_plems_fragment() -> None:
    uri = "file:///etc/cyclonedds.xml"
    settings = from_env({"CYCLONEDDS_URI": uri, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    config = settings.cyclone_config()
    assert config.endswith("," + uri)
    plem_xml(settings)
    assert from_env({"CYCLONEDDS_URI": uri, "ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT"}).cyclone_config() == uri


def test_subnet_fragment() -> None:
    root = plem_xml(DiscoverySettings(discovery_range="SUBNET"))
    assert root.find("Domain/General/AllowMulticast") is None   # multicast stays on
    assert root.findtext("Domain/Discovery/ParticipantIndex") == "auto"
    assert root.findtext("Domain/Discovery/MaxAutoParticipantIndex") == "32"
    assert root.find("Domain/Discovery/Peers") is None


def test_localhost_fragment() -> None:
    root = plem_xml(DiscoverySettings(discovery_range="LOCALHOST"))
    assert root.findtext("Domain/General/AllowMulticast") == "false"
    assert [peer.get("address") for peer in root.iterfind("Domain/Discovery/Peers/Peer")] == ["localhost"]
    assert root.findtext("Domain/Discovery/ParticipantIndex") == "auto"
    assert root.findtext("Domain/Discovery/MaxAutoParticipantIndex") == "32"


def test_off_fragment() -> None:
    root = plem_xml(DiscoverySettings(discovery_range="OFF", static_peers=("10.0.0.2",)))
    assert root.findtext("Domain/General/AllowMulticast") == "false"
    assert root.findtext("Domain/Discovery/ParticipantIndex") == "none"
    assert root.findtext("Domain/Discovery/Tag")
    assert root.find(".//Peer") is None


def test_system_default_adds_nothing() -> None:
    assert DiscoverySettings(discovery_range="SYSTEM_DEFAULT").cyclone_config() == ""


#: A different random domain for each range, so no two of these nodes ever share one.
NODE_DOMAINS = {discovery_range: fresh_domain() for discovery_range in RANGES}


@pytest.mark.parametrize("discovery_range", RANGES)
def test_node_comes_up(discovery_range: str) -> None:
    """Cyclone DDS accepts the configuration of every range (a bad one fails Domain creation)."""
    domain = NODE_DOMAINS[discovery_range]
    peers = ("127.0.0.1", "udp/localhost:7410")   # every form of peer plem lets through
    node = Node(DiscoverySettings(domain_id=domain, discovery_range=discovery_range, static_peers=peers))
    try:
        assert node.domain_id == domain
        assert node.participant.get_qos() is not None
        publisher = node.publisher("/discovery_check/chatter", "std_msgs/msg/String", DEFAULT)
        publisher.publish(publisher.message(data="x"))
        assert publisher.published == 1
    finally:
        node.close()



def test_user_config_reaches_cyclone() -> None:
    """CYCLONEDDS_URI is applied: an invalid value in it stops the node, as an error naming the variable."""
    bad = "<CycloneDDS><Domain><Discovery><MaxAutoParticipantIndex>many</MaxAutoParticipantIndex></Discovery>" \
          "</Domain></CycloneDDS>"
    settings = from_env({"ROS_DOMAIN_ID": str(fresh_domain()), "CYCLONEDDS_URI": bad})
    with pytest.raises(ConfigError) as caught:
        Node(settings)
    assert "CYCLONEDDS_URI" in caught.value.why and "CYCLONEDDS_URI" in caught.value.how


@pytest.mark.parametrize(("variable", "value"), [("ROS_STATIC_PEERS", "0"), ("ROS_STATIC_PEERS", "nonexistent.invalid"),
                                                 ("ROS_AUTOMATIC_DISCOVERY_RANGE", "lan"),
                                                 ("ROS_SECURITY_ENABLE", "true")])
def test_plem_topic_reports_the_error_instead_of_crashing(variable: str, value: str) -> None:
    """The real command: exit 1 with ERROR/WHAT/WHY/HOW, not Cyclone's abort (exit -6) or a traceback."""
    finished = run_plem("topic", "list", "--timeout", "0.1", env={variable: value})
    assert finished.returncode == 1, finished
    assert f"ERROR: {variable}" in finished.stderr and "Traceback" not in finished.stderr


def test_plem_launch_refuses_security_before_the_arm_starts(tmp_path: Path) -> None:
    """SROS2 asked for: the launch stops with the error before any RT driver or bridge runs."""
    robot_id = f"sros_{uuid.uuid4().hex[:8]}"
    finished = run_plem("launch", "bus:=mock", f"robot_id:={robot_id}", "record:=false",
                        env={"ROS_SECURITY_ENABLE": "true", "TMPDIR": str(tmp_path)})
    assert finished.returncode == 1, finished
    assert "ERROR: ROS_SECURITY_ENABLE='true'" in finished.stderr and "Traceback" not in finished.stderr
    assert "rt_driver" not in finished.stdout and not list(SHM_DIRECTORY.glob(f"{robot_id}_*"))
