"""Cost of `plem validate` against rendering the same xacro alone, per built-in description package.

Usage: python benchmarks/validate_vs_xacro.py [--repeat N] [--cli-runs N].
Every measurement interleaves the two sides (A, B, A, B ...). The whole commands run from compiled bytecode on
both sides: plem's modules are compiled first, as an installed package has them (xacro's already are).
"""

from __future__ import annotations

import argparse
import compileall
import importlib.metadata
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import xacro

import plem
import plem.description.render  # noqa: F401  (patches xacro's $(find) to plem's package search; both sides use it)
from plem.core.config.loader import ConfigLoader
from plem.core.paths import BUILTIN_PACKAGES_DIR, find_package
from plem.description.discover import URDF_SUFFIX
from plem.description.validate import validate_package

PACKAGES = tuple(f"{kind}_description"
                 for kind in ("indy7", "indy7_v2", "indy12", "indy12_v2", "indyrp2", "indyrp2_v2"))
WARMUP = 3
CLI_WARMUP = 1
TARGET_RATIO = 1.3
BIN = Path(sys.executable).parent
SHARE_VARIABLE = "BENCH_SHARE_DIR"
# Without ROS, the xacro command resolves $(find pkg) through a missing ament_index_python; this stand-in answers it
# with the same directories plem's search path gives for its built-in packages, so the command runs unmodified.
AMENT_STAND_IN = f'''"""ament_index_python stand-in for the benchmark: the share directory of a built-in package."""
import os


def get_package_share_directory(package_name):
    return os.path.join(os.environ["{SHARE_VARIABLE}"], package_name)
'''

Job = tuple[Callable[[], object], Callable[[], object]]  # (untimed preparation, timed call)


@dataclass(frozen=True)
class Samples:
    """Wall times of one side, in milliseconds."""

    ms: tuple[float, ...]

    @property
    def median(self) -> float:
        return statistics.median(self.ms)

    @property
    def p10(self) -> float:
        return statistics.quantiles(self.ms, n=10, method="inclusive")[0]

    @property
    def p90(self) -> float:
        return statistics.quantiles(self.ms, n=10, method="inclusive")[-1]


def interleave(jobs: Sequence[Job], repeat: int, warmup: int) -> list[Samples]:
    """Run the jobs in turn `warmup` times untimed, then `repeat` times timed; one Samples per job."""
    times: list[list[float]] = [[] for _ in jobs]
    for round_index in range(warmup + repeat):
        for (prepare, call), bucket in zip(jobs, times, strict=False):
            prepare()
            start = time.perf_counter()
            call()
            elapsed = (time.perf_counter() - start) * 1000.0
            if round_index >= warmup:
                bucket.append(elapsed)
    return [Samples(tuple(bucket)) for bucket in times]


def urdf_path(package: str) -> Path:
    """The package's single urdf/*.urdf.xacro, found the way plem's discovery does."""
    (path,) = sorted((find_package(package) / "urdf").glob(f"*{URDF_SUFFIX}"))
    return path


def nothing() -> None:
    """No preparation."""


def fresh_yaml_cache() -> None:
    """Forget plem's parsed YAML, as a new `plem validate` process would have none."""
    ConfigLoader.get_instance().invalidate()


def in_process_jobs(package: str) -> list[Job]:
    """(A) plem's full validation by package name; (B) xacro rendering the same URDF, alone."""
    report = validate_package(package)
    if not report.passed():
        raise SystemExit(f"{package} does not validate; timing a failing validation would mean nothing")
    path = os.fspath(urdf_path(package))
    return [(fresh_yaml_cache, lambda: validate_package(package)),
            (nothing, lambda: xacro.process_file(path).toxml())]


def command_job(command: list[str], env: dict[str, str]) -> Job:
    """Run `command` to completion, output discarded."""
    return nothing, lambda: subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def commands(package: str) -> tuple[list[str], list[str]]:
    """The two whole commands compared: `plem validate PKG` and `xacro URDF`."""
    return [str(BIN / "plem"), "validate", package], [str(BIN / "xacro"), os.fspath(urdf_path(package))]


def failure(command: list[str], env: dict[str, str]) -> str | None:
    """None when `command` succeeds, else the end of its output."""
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    return None if done.returncode == 0 else (done.stderr or done.stdout).strip()[-300:] or f"exit {done.returncode}"


def print_table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    widths = [max(len(cell) for cell in column) for column in zip(headers, *rows, strict=False)]
    for line in (headers, ["-" * width for width in widths], *rows):
        print("  ".join(cell.ljust(width) for cell, width in zip(line, widths, strict=False)).rstrip())


def ratio_cells(plem: Samples, bare: Samples) -> list[str]:
    ratio = plem.median / bare.median
    return [f"{ratio:.2f}x", "yes" if ratio <= TARGET_RATIO else "NO"]


def in_process_table(repeat: int) -> None:
    print(f"\nIn-process, {WARMUP} warm-ups then {repeat} interleaved repetitions each; ms")
    rows = []
    for package in PACKAGES:
        plem, bare = interleave(in_process_jobs(package), repeat, WARMUP)
        rows.append([package, f"{plem.median:.2f}", f"{plem.p90:.2f}", f"{bare.median:.2f}", f"{bare.p90:.2f}",
                     *ratio_cells(plem, bare)])
    print_table(["package", "plem median", "plem p90", "xacro median", "xacro p90", "ratio",
                 f"<= {TARGET_RATIO}x"], rows)


def command_table(env: dict[str, str], runs: int) -> None:
    print(f"\nWhole command as a subprocess, {CLI_WARMUP} warm-up then {runs} interleaved runs each; ms "
          "(median, and p10-p90 for the spread)")
    plem_command, xacro_command = commands(PACKAGES[0])
    print(f"  A: {shlex.join(plem_command)}\n  B: {shlex.join(xacro_command)}\n  (likewise for every package; both "
          f"run with PYTHONPATH={env['PYTHONPATH']}, whose ament_index_python stand-in lets xacro resolve $(find))")
    for side, command in (("plem validate", plem_command), ("xacro", xacro_command)):
        if (error := failure(command, env)) is not None:
            print(f"{side} CLI not available: {error}")
            return
    compileall.compile_dir(Path(plem.__file__).parent, quiet=1)
    rows = []
    for package in PACKAGES:
        plem_side, bare = interleave([command_job(c, env) for c in commands(package)], runs, CLI_WARMUP)
        rows.append([package, f"{plem_side.median:.1f}", f"{plem_side.p10:.1f}-{plem_side.p90:.1f}",
                     f"{bare.median:.1f}", f"{bare.p10:.1f}-{bare.p90:.1f}", *ratio_cells(plem_side, bare)])
    print_table(["package", "plem validate median", "p10-p90", "xacro median", "p10-p90", "ratio",
                 f"<= {TARGET_RATIO}x"], rows)


def print_machine() -> None:
    print(f"command: {shlex.join([sys.executable, *sys.argv])}")
    print(f"machine: nproc={len(os.sched_getaffinity(0))}, {platform.machine()}, {platform.platform()}")
    print(f"python {platform.python_version()} ({sys.executable}); plem {importlib.metadata.version('plem')}, "
          f"xacro {importlib.metadata.version('xacro')}")


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=30, help="timed in-process repetitions per side (>= 30)")
    parser.add_argument("--cli-runs", type=int, default=30, help="timed whole-command runs per side (>= 10)")
    args = parser.parse_args(argv)
    if args.repeat < 30:
        parser.error("--repeat must be at least 30")
    if args.cli_runs < 10:
        parser.error("--cli-runs must be at least 10")
    print_machine()
    in_process_table(args.repeat)
    with tempfile.TemporaryDirectory(prefix="plem-bench-") as shim:
        (Path(shim) / "ament_index_python").mkdir()
        (Path(shim) / "ament_index_python" / "__init__.py").write_text("", encoding="utf-8")
        (Path(shim) / "ament_index_python" / "packages.py").write_text(AMENT_STAND_IN, encoding="utf-8")
        python_path = os.pathsep.join(filter(None, (shim, os.environ.get("PYTHONPATH"))))
        command_table({**os.environ, "PYTHONPATH": python_path, SHARE_VARIABLE: os.fspath(BUILTIN_PACKAGES_DIR)},
                      args.cli_runs)


if __name__ == "__main__":
    main()
