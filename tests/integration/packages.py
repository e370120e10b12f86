"""Test helpers for description packages: copy a built-in one somewhere writable, fingerprint a tree."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

from plem.core.paths import BUILTIN_PACKAGES_DIR

BUILTIN_TYPES = ("indy7", "indy7_v2", "indy12", "indy12_v2", "indyrp2", "indyrp2_v2")


def copy_builtin(robot_type: str, destination: Path) -> Path:
    """A writable copy of `<robot_type>_description` under `destination` (same directory name)."""
    target = destination / f"{robot_type}_description"
    shutil.copytree(BUILTIN_PACKAGES_DIR / target.name, target)
    return target


def tree_fingerprint(root: Path) -> dict[str, str]:
    """Relative path → sha256 of every file, to prove a tree was not modified."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}
