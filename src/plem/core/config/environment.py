"""System-wide environment variables that are not arm fields: PLEM_HOME, ROS_DOMAIN_ID, RMW_IMPLEMENTATION."""

from __future__ import annotations

import os
import stat
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from plem.core.config.settings import Setting, parse_int
from plem.core.files import file_kind
from plem.errors import ConfigError

DEFAULT_HOME = "~/.plem"
SPEC_DOMAIN_RANGE = range(0, 102)
ROS_DOMAIN_MAX = 232  # highest id whose DDS ports still fit below 65535 on Linux
RESERVED_DOMAIN_ID = 215
CYCLONE_RMW = "rmw_cyclonedds_cpp"

DOMAIN_SETTING = Setting(
    "ros_domain_id", parse_int, "a whole number from 0 to 101", "ROS 2 DDS domain", env="ROS_DOMAIN_ID"
)


def plem_home(environ: Mapping[str, str] | None = None) -> Path:
    """plem's per-user folder: `PLEM_HOME`, default `~/.plem`; a folder, or not there yet (created on use).

    Anything else (a regular file, /dev/null, a path through a file) is a ConfigError naming PLEM_HOME.
    """
    env = os.environ if environ is None else environ
    given = env.get("PLEM_HOME")
    home = Path(given or DEFAULT_HOME).expanduser()
    try:
        mode = home.stat().st_mode
    except FileNotFoundError:
        return home
    except OSError as error:
        found = error.strerror or str(error)
    else:
        if stat.S_ISDIR(mode):
            return home
        found = f"it is a {file_kind(mode)}"
    origin = f"PLEM_HOME={given}" if given else f"PLEM_HOME is unset, so {DEFAULT_HOME}"
    raise ConfigError(
        f"PLEM_HOME is not a folder: {home}",
        what="PLEM_HOME naming a folder (plem keeps robot profiles in $PLEM_HOME/profiles), or a path where "
             "one can be created",
        why=f"{origin}: {home} cannot be used as a folder: {found}",
        how=f"export PLEM_HOME=/path/to/a/folder, or unset PLEM_HOME to use {DEFAULT_HOME}"
            if given else f"move {home} out of the way, or export PLEM_HOME=/path/to/a/folder",
    )


@dataclass
class MiddlewareEnvironment:
    """The DDS domain and middleware settings in effect, with warnings about questionable values."""

    ros_domain_id: int
    ros_domain_source: str
    rmw_implementation: str
    rmw_source: str
    warnings: list[str] = field(default_factory=list)


def middleware_environment(environ: Mapping[str, str] | None = None) -> MiddlewareEnvironment:
    """Read and check ROS_DOMAIN_ID and RMW_IMPLEMENTATION; never silently use a bad domain id."""
    env = os.environ if environ is None else environ
    warnings: list[str] = []
    raw_domain = env.get("ROS_DOMAIN_ID", "").strip()
    if raw_domain:
        domain = DOMAIN_SETTING.from_text(raw_domain, "ROS_DOMAIN_ID")
        domain_source = "environment ROS_DOMAIN_ID"
        _check_domain(domain, warnings)
    else:
        domain, domain_source = 0, "default (ROS_DOMAIN_ID unset)"
    rmw = env.get("RMW_IMPLEMENTATION", "").strip()
    if rmw and rmw != CYCLONE_RMW:
        warnings.append(
            f"RMW_IMPLEMENTATION={rmw} is ignored: plem speaks the ROS 2 DDS wire protocol through Cyclone DDS "
            f"({CYCLONE_RMW}); ROS 2 nodes using {rmw} still interoperate on the same domain"
        )
    return MiddlewareEnvironment(
        ros_domain_id=domain,
        ros_domain_source=domain_source,
        rmw_implementation=CYCLONE_RMW,
        rmw_source="environment RMW_IMPLEMENTATION" if rmw == CYCLONE_RMW else "plem default",
        warnings=warnings,
    )


def _check_domain(domain: int, warnings: list[str]) -> None:
    if domain in SPEC_DOMAIN_RANGE:
        return
    if domain == RESERVED_DOMAIN_ID or not 0 <= domain <= ROS_DOMAIN_MAX:
        if domain == RESERVED_DOMAIN_ID:
            reason = "215 is reserved"
        elif domain < 0:
            reason = f"a domain id cannot be negative (usable ids are 0 to {ROS_DOMAIN_MAX})"
        else:
            reason = f"ids above {ROS_DOMAIN_MAX} give UDP ports past 65535"
        raise ConfigError(
            f"ROS_DOMAIN_ID {domain} cannot be used",
            what="ROS_DOMAIN_ID from 0 to 101",
            why=f"ROS_DOMAIN_ID is {domain}; {reason}",
            how="export ROS_DOMAIN_ID=42 (any value 0-101, the same on every machine that should talk)",
        )
    warnings.append(
        f"ROS_DOMAIN_ID={domain} is outside 0-101: its DDS ports may collide with the ephemeral port range; "
        "prefer a value from 0 to 101"
    )
