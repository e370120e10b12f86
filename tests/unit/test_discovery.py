"""Domain and discovery settings from the ROS 2 environment variables, and the Cyclone DDS XML they make."""

from __future__ import annotations


import pytest
from cyclonedds.core import DDSException
from lxml import etree

from plem.errors import ConfigError
from plem.middleware.discovery import MAX_DOMAIN_ID, RANGES, DiscoverySettings
from plem.middleware.node import Node
from plem.middleware.qos import DEFAULT
from tests.conftest import fresh_domain

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
    ("localhost", "LOCALHOST"), ("Off", "OFF"), (" system_default ", "SYSTEM_DEFAULT"), ("", "SUBNET"),
])
def test_discovery_range(text: str, expected: str) -> None:
    assert from_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": text}).discovery_range == expected


@pytest.mark.parametrize("text", ["LAN", "local", "SUBNETS", "0", "LOCAL HOST"])
def test_invalid_discovery_range(text: str) -> None:
    with pytest.raises(ConfigError) as caught:
        from_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": text})
    rendered = caught.value.render()
    assert all(f"\n{label}: " in rendered for label in ("WHAT", "WHY", "HOW"))
    assert repr(text) in rendered
    assert all(name in caught.value.what for name in RANGES)


def test_localhost_only_means_localhost_without_static_peers() -> None:
    settings = from_env({"ROS_LOCALHOST_ONLY": "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
                         "ROS_STATIC_PEERS": "10.0.0.2"})
    assert (settings.discovery_range, settings.static_peers) == ("LOCALHOST", ())
    peers = [peer.get("address") for peer in plem_xml(settings).iter("Peer")]
    assert peers == ["localhost"]


def test_localhost_only_zero_changes_nothing() -> None:
    settings = from_env({"ROS_LOCALHOST_ONLY": "0", "ROS_STATIC_PEERS": "10.0.0.2"})
    assert (settings.discovery_range, settings.static_peers) == ("SUBNET", ("10.0.0.2",))


def test_static_peers_in_config() -> None:
    settings = from_env({"ROS_STATIC_PEERS": " robot-pc.local ; ;192.168.1.7;"})
    assert settings.static_peers == ("robot-pc.local", "192.168.1.7")
    assert [peer.get("address") for peer in plem_xml(settings).iter("Peer")] == ["robot-pc.local", "192.168.1.7"]
    assert "static peers robot-pc.local, 192.168.1.7" in settings.describe()
    local = from_env({"ROS_STATIC_PEERS": "a;b", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    assert [peer.get("address") for peer in plem_xml(local).iter("Peer")] == ["localhost", "a", "b"]


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
    node = Node(DiscoverySettings(domain_id=domain, discovery_range=discovery_range, static_peers=("127.0.0.1",)))
    try:
        assert node.domain_id == domain
        assert node.participant.get_qos() is not None
        publisher = node.publisher("/discovery_check/chatter", "std_msgs/msg/String", DEFAULT)
        publisher.publish(publisher.message(data="x"))
        assert publisher.published == 1
    finally:
        node.close()



def test_user_config_reaches_cyclone() -> None:
    """CYCLONEDDS_URI is applied: an invalid value in it stops the node from coming up."""
    bad = "<CycloneDDS><Domain><Discovery><MaxAutoParticipantIndex>many</MaxAutoParticipantIndex></Discovery>" \
          "</Domain></CycloneDDS>"
    settings = from_env({"ROS_DOMAIN_ID": str(fresh_domain()), "CYCLONEDDS_URI": bad})
    with pytest.raises(DDSException):
        Node(settings)
