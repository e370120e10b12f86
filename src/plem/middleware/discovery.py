"""The ROS 2 environment of plem's DDS participants: domain, discovery range, static peers, security.

The variables are read as ROS 2 Jazzy's rcl reads them and turned into the Cyclone DDS configuration
rmw_cyclonedds_cpp builds on Jazzy:

| ROS_AUTOMATIC_DISCOVERY_RANGE | multicast | unicast peers               | participant index            |
|-------------------------------|-----------|-----------------------------|------------------------------|
| SUBNET (the default)          | on        | ROS_STATIC_PEERS            | auto, at most 32 on a host   |
| LOCALHOST                     | off       | localhost, ROS_STATIC_PEERS | auto, at most 32 on a host   |
| OFF                           | off       | none                        | none, plus a domain tag of this process |
| SYSTEM_DEFAULT                | Cyclone DDS's own defaults, nothing added                                |

`ROS_LOCALHOST_ONLY=1` (deprecated) means LOCALHOST without static peers. A user's `CYCLONEDDS_URI` is
applied after plem's settings. Where Jazzy warns and carries on with a guess (an unknown range, a peer
that is too long), or Cyclone DDS would abort the process (a peer it cannot resolve), plem stops with
an error instead, before any participant exists. SROS2 is refused: see `_check_security`.
"""

from __future__ import annotations

import logging
import os
import re
import socket
from collections.abc import Mapping
from dataclasses import dataclass

from plem.errors import ConfigError

#: Highest domain id the RTPS port mapping allows; ROS 2 calls 0-101 safe on Linux.
MAX_DOMAIN_ID = 232
RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")
#: rmw's limit on one static peer (RMW_DISCOVERY_OPTIONS_STATIC_PEERS_MAX_LENGTH, less the terminating NUL).
MAX_PEER_LENGTH = 255
_PEER = re.compile(r"(?:udp/)?(?P<host>[A-Za-z0-9_.\-]+)(?::(?P<port>[0-9]{1,5}))?")
_PEER_EXAMPLE = "export ROS_STATIC_PEERS='192.168.0.10;robot-pc.local:7410'"
_log = logging.getLogger("plem.dds")


@dataclass(frozen=True)
class DiscoverySettings:
    """Domain id, discovery range, static peers and any user Cyclone configuration."""

    domain_id: int = 0
    discovery_range: str = "SUBNET"
    static_peers: tuple[str, ...] = ()
    user_config: str = ""
    #: Cyclone drops larger samples, sent or received, before it reassembles them (None: Cyclone's 2 GiB).
    max_sample_bytes: int | None = None

    @classmethod
    def from_environment(cls, environ: Mapping[str, str] | None = None) -> DiscoverySettings:
        """Settings from ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_STATIC_PEERS and ROS_LOCALHOST_ONLY.

        Raises ConfigError for any value ROS 2 Jazzy would not take as written, and for ROS_SECURITY_ENABLE.
        """
        env = os.environ if environ is None else environ
        _check_security(env.get("ROS_SECURITY_ENABLE", ""))
        domain_id = _domain_id(env.get("ROS_DOMAIN_ID", ""))
        discovery_range = _discovery_range(env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", ""))
        peers = _static_peers(env.get("ROS_STATIC_PEERS", ""))
        if _localhost_only(env.get("ROS_LOCALHOST_ONLY", "")):
            discovery_range, peers = "LOCALHOST", ()
        elif peers and discovery_range in ("OFF", "SYSTEM_DEFAULT"):
            _log.warning("ROS_STATIC_PEERS is ignored: ROS_AUTOMATIC_DISCOVERY_RANGE=%s adds no peers",
                         discovery_range)
            peers = ()
        return cls(domain_id, discovery_range, peers, env.get("CYCLONEDDS_URI", ""))

    def cyclone_config(self) -> str:
        """Cyclone DDS configuration for this domain: plem's discovery fragment, then the user's."""
        if self.discovery_range == "SYSTEM_DEFAULT":
            fragment = ""
        elif self.discovery_range == "OFF":
            fragment = ("<General><AllowMulticast>false</AllowMulticast></General>"
                        f"<Discovery><ParticipantIndex>none</ParticipantIndex><Tag>ros_discovery_off_{os.getpid()}"
                        "</Tag></Discovery>")
        else:
            local = self.discovery_range == "LOCALHOST"
            peers = (["localhost"] if local else []) + list(self.static_peers)
            peer_xml = "".join(f'<Peer address="{peer}"/>' for peer in peers)
            fragment = (("<General><AllowMulticast>false</AllowMulticast></General>" if local else "")
                        + "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
                        "<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex>"
                        + (f"<Peers>{peer_xml}</Peers>" if peer_xml else "") + "</Discovery>")
        if self.max_sample_bytes is not None:
            fragment += f"<Internal><MaxSampleSize>{self.max_sample_bytes}B</MaxSampleSize></Internal>"
        parts = [f"<CycloneDDS><Domain>{fragment}</Domain></CycloneDDS>"] if fragment else []
        if self.user_config:
            parts.append(self.user_config)
        return ",".join(parts)

    def describe(self) -> str:
        """One line for summaries and warnings: domain, range and peers."""
        peers = f", static peers {', '.join(self.static_peers)}" if self.static_peers else ""
        return f"ROS_DOMAIN_ID={self.domain_id}, discovery {self.discovery_range.lower()}{peers}"


def _domain_id(text: str) -> int:
    if not text.strip():
        return 0
    try:
        value = int(text.strip())
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_DOMAIN_ID:
        raise ConfigError(f"ROS_DOMAIN_ID={text!r} is not a usable domain id",
                          what=f"a whole number from 0 to {MAX_DOMAIN_ID} (0-101 is safe on Linux)",
                          why=f"the variable is set to {text!r}", how="export ROS_DOMAIN_ID=42, or unset it for 0")
    return value


def _discovery_range(text: str) -> str:
    """The range as rcl reads it: exactly one of RANGES, upper case; empty means SUBNET."""
    if text == "":
        return "SUBNET"
    if text not in RANGES:
        raise ConfigError(f"ROS_AUTOMATIC_DISCOVERY_RANGE={text!r} is not a discovery range",
                          what=f"exactly one of {', '.join(RANGES)} (upper case, as ROS 2 reads it), or unset "
                               "for SUBNET",
                          why=f"ROS 2 nodes would not read {text!r} as any range (Jazzy falls back to LOCALHOST "
                              "with a warning), so plem refuses to guess",
                          how="export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (or unset it for SUBNET)")
    return text


def _static_peers(text: str) -> tuple[str, ...]:
    """The ';'-separated peers (empty items skipped, as rcl does), each checked as Cyclone DDS will use it."""
    peers = tuple(peer.strip() for peer in text.split(";") if peer.strip())
    for peer in peers:
        problem = _peer_problem(peer)
        if problem:
            raise ConfigError(f"ROS_STATIC_PEERS names a peer plem cannot use: {peer!r}",
                              what=f"host names or IPv4 addresses, each at most {MAX_PEER_LENGTH} characters, "
                                   "optionally with udp/ before and :PORT after, separated by ';'",
                              why=f"{problem} (ROS_STATIC_PEERS={text!r})",
                              how=f"{_PEER_EXAMPLE} with names this host can resolve, or unset ROS_STATIC_PEERS")
    return peers


def _peer_problem(peer: str) -> str | None:
    """Why Cyclone DDS could not use `peer` (it aborts the process on such a peer), or None."""
    match = _PEER.fullmatch(peer)
    if match is None or len(peer) > MAX_PEER_LENGTH:
        return f"{peer!r} is not a host name or IPv4 address with an optional :PORT"
    if match["port"] is not None and not 1 <= int(match["port"]) <= 65535:
        return f"port {match['port']} is not between 1 and 65535"
    try:
        addresses = {info[4][0] for info in socket.getaddrinfo(match["host"], None, socket.AF_INET)}
    except (OSError, UnicodeError):
        return f"{match['host']!r} does not resolve to an IPv4 address on this host"
    if addresses == {"0.0.0.0"}:
        return f"{match['host']!r} is the unspecified address 0.0.0.0, not a host"
    return None


def _localhost_only(text: str) -> bool:
    """ROS_LOCALHOST_ONLY as Jazzy reads it: 1 on, 0 off, both deprecated; unset or empty: not used."""
    if text == "":
        return False
    if text not in ("0", "1"):
        raise ConfigError(f"ROS_LOCALHOST_ONLY={text!r} is not 1 or 0",
                          what="1 (discovery on this host only) or 0; the variable is deprecated since ROS 2 Jazzy",
                          why=f"ROS 2 reads only a leading '1' as on, so {text!r} would not mean what it says",
                          how="unset ROS_LOCALHOST_ONLY and export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST instead")
    effect = ("discovery stays on this host; ROS_AUTOMATIC_DISCOVERY_RANGE and ROS_STATIC_PEERS are ignored"
              if text == "1" else "it changes nothing")
    _log.warning("ROS_LOCALHOST_ONLY is deprecated since ROS 2 Jazzy but still honoured: %s. Use "
                 "ROS_AUTOMATIC_DISCOVERY_RANGE and ROS_STATIC_PEERS instead", effect)
    return text == "1"


def _check_security(text: str) -> None:
    """Refuse SROS2: the Cyclone DDS of the `cyclonedds` Python package is built without DDS Security.

    Its library ships no security plugins (libdds_security_auth, _ac, _crypto) and rejects the
    `<Security>` configuration element, so plem cannot honour ROS_SECURITY_* and will not start
    unprotected when security was asked for. Any value but empty, 0 or false asks for it.
    """
    if text.lower() in ("", "0", "false"):
        return
    raise ConfigError(f"ROS_SECURITY_ENABLE={text!r}: plem cannot secure its DDS traffic (SROS2)",
                      what="ROS_SECURITY_ENABLE unset, 0 or false: plem's ROS 2 bridge and tools run DDS without "
                           "security",
                      why="the Cyclone DDS library of the cyclonedds Python package is built without DDS Security "
                          "(no libdds_security_* plugins, no <Security> configuration), and starting anyway would "
                          "put the robot on the network unprotected",
                      how="unset ROS_SECURITY_ENABLE and keep the network closed instead: "
                          "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, bridge_commands:=false or bridge:=false "
                          "(see docs/security.md)")
