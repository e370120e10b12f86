"""Run the real `plem` console script as a user would, capturing what it prints."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path


def plem_executable() -> str:
    """The installed entry point next to this interpreter (falls back to PATH)."""
    candidate = Path(sys.executable).parent / "plem"
    return str(candidate) if candidate.exists() else (shutil.which("plem") or "plem")


def run_plem(*args: str, env: dict[str, str] | None = None, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    """Run `plem ARGS` with the test's environment (plus `env`) and return the finished process."""
    return subprocess.run([plem_executable(), *args], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, **(env or {})})
