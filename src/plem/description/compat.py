"""PLEM_COMPAT_VERSION: which version of the description-package protocol a package was written for."""

from __future__ import annotations

import re
from pathlib import Path

from plem.core.files import read_regular_text
from plem.description.problems import Findings
from plem.errors import ConfigError

PROTOCOL_VERSION = "1.0.0"
#: Digits of one version part: no protocol will number past this, and longer parts are refused, not converted.
MAX_PART_DIGITS = 9
_PART = rf"(0|[1-9]\d{{0,{MAX_PART_DIGITS - 1}}})"
_SEMVER = re.compile(rf"{_PART}\.{_PART}\.{_PART}(?:-[0-9A-Za-z.-]+)?(?:\+[0-9A-Za-z.-]+)?")
#: The file holds one version; a larger file is refused unread.
MAX_COMPAT_BYTES = 64 * 1024
#: Characters of a malformed version quoted in the error.
MAX_SHOWN = 40


def check_compat_version(path: Path | None, root: Path, found: Findings) -> None:
    """Exists, is SemVer, same major as plem's protocol; a newer minor only warns."""
    if path is None:
        found.error("compat.missing", "PLEM_COMPAT_VERSION is missing",
                    what="a PLEM_COMPAT_VERSION file at the package root holding a SemVer version",
                    why=f"{root / 'PLEM_COMPAT_VERSION'} does not exist",
                    how=f"echo {PROTOCOL_VERSION} > {root / 'PLEM_COMPAT_VERSION'}", file=root)
        return
    try:
        text = read_regular_text(path, MAX_COMPAT_BYTES, "PLEM_COMPAT_VERSION file").strip()
    except ConfigError as error:
        found.add("compat.unreadable", error, file=path)
        return
    match = _SEMVER.fullmatch(text)
    if not match:
        shown = repr(text) if len(text) <= MAX_SHOWN else f"{text[:MAX_SHOWN]!r}... ({len(text)} characters)"
        found.error("compat.semver", "PLEM_COMPAT_VERSION is not a SemVer version",
                    what=f"MAJOR.MINOR.PATCH, e.g. 1.0.0, each part at most {MAX_PART_DIGITS} digits",
                    why=f"found {shown}", how=f"write {PROTOCOL_VERSION} into the file", file=path, line=1)
        return
    major, minor, _ = (int(part) for part in match.groups())
    ours_major, ours_minor, _ = (int(part) for part in PROTOCOL_VERSION.split("."))
    if major != ours_major:
        found.error("compat.major", f"Package needs protocol {text}, plem implements {PROTOCOL_VERSION}",
                    what=f"a package for protocol {ours_major}.x", why=f"PLEM_COMPAT_VERSION is {text}",
                    how=f"port the package to protocol {PROTOCOL_VERSION} and update the file, or use a plem "
                        f"release for protocol {major}.x", file=path, line=1)
    elif minor > ours_minor:
        found.warning("compat.minor_newer", f"Package targets a newer protocol ({text}) than plem's {PROTOCOL_VERSION}",
                      what=f"protocol {ours_major}.{ours_minor} or older", why=f"PLEM_COMPAT_VERSION is {text}",
                      how="upgrade plem, or check that the package uses no newer features", file=path, line=1)
