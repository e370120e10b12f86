"""Which DDS domain plem joins and how far discovery reaches, read from the ROS 2 environment variables.

`ROS_DOMAIN_ID` picks the domain (default 0). `ROS_AUTOMATIC_DISCOVERY_RANGE` (SUBNET, LOCALHOST, OFF,
SYSTEM_DEFAULT) and `ROS_STATIC_PEERS` shape discovery the way rmw_cyclonedds does on ROS 2 Jazzy; the
older `ROS_LOCALHOST_ONLY=1` means LOCALHOST. A user's `CYCLONEDDS_URI` is applied after plem's settings.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass

from plem.errors import ConfigError

#: Highest domain id the RTPS port mapping allows; ROS 2 calls 0-101 safe on Linux.
MAX_DOMAIN_ID = 232
_PEER = re.compile(r"[A-Za-z0-9_.:\-\[\]]+")
RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")


@dataclass(frozen=True)
class DiscoverySettings:
    """Domain id, discovery range, static peers and any user Cyclone configuration."""

    domain_id: int = 0
    discovery_range: str = "SUBNET"
    static_peers: tuple[str, ...] = ()
    user_config: str = ""

    @classmethod
    def from_environment(cls, environ: Mapping[str, str] | None = None) -> DiscoverySettings:
        """Settings from ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_STATIC_PEERS, ROS_LOCALHOST_ONLY."""
        env = os.environ if environ is None else environ
        discovery_range = env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper() or "SUBNET"
        if discovery_range not in RANGES:
            raise ConfigError(f"ROS_AUTOMATIC_DISCOVERY_RANGE={env['ROS_AUTOMATIC_DISCOVERY_RANGE']!r} is not known",
                              what=f"one of {', '.join(RANGES)}", why="the variable is set to something else",
                              how="export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (or unset it for SUBNET)")
        peers = tuple(peer.strip() for peer in env.get("ROS_STATIC_PEERS", "").split(";") if peer.strip())
        for peer in peers:
            if not _PEER.fullmatch(peer):
                raise ConfigError(f"ROS_STATIC_PEERS names an unusable peer {peer!r}",
                                  what="host names or IP addresses separated by ';'",
                                  why=f"ROS_STATIC_PEERS={env['ROS_STATIC_PEERS']!r}",
                                  how="export ROS_STATIC_PEERS='192.168.0.10;robot-pc.local'")
        if env.get("ROS_LOCALHOST_ONLY", "").strip() == "1":
            discovery_range, peers = "LOCALHOST", ()
        return cls(_domain_id(env.get("ROS_DOMAIN_ID", "")), discovery_range, peers,
                   env.get("CYCLONEDDS_URI", ""))

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
        parts = [f"<CycloneDDS><Domain>{fragment}</Domain></CycloneDDS>"] if fragment else []
        if self.user_config:
            parts.append(self.user_config)
        return ",".join(parts)

    def describe(self) -> str:
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
