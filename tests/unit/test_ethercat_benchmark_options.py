"""benchmarks/ethercat.py's options: every combination either runs to its end or is refused with a usage message
(never a traceback), and a run without the soak measures the pairs alone."""

from __future__ import annotations

import importlib.util
import itertools
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture(scope="module")
def benchmark() -> ModuleType:
    sys.path.insert(0, str(BENCHMARKS))   # its sibling modules (launching, loop_latency), as `python benchmarks/…`
    try:
        spec = importlib.util.spec_from_file_location("ethercat_benchmark", BENCHMARKS / "ethercat.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(BENCHMARKS))


@pytest.mark.parametrize(("soak", "pairs", "window", "quick", "bare"), list(itertools.product(
    (None, "0", "0.01", "0.5"), (None, "0", "2"), (None, "1", "0.5"), (False, True), (False, True))))
def test_every_combination_is_either_runnable_or_refused_with_a_reason(benchmark, capsys, soak, pairs, window,
                                                                       quick, bare):
    argv = [*(["--soak-minutes", soak] if soak else []), *(["--pairs", pairs] if pairs else []),
            *(["--window", window] if window else []), *(["--quick"] if quick else []),
            *(["--bare-soak"] if bare else [])]
    try:
        args = benchmark.arguments(argv)
    except SystemExit as refused:
        assert refused.code == 2
        assert "error:" in capsys.readouterr().err
        return
    assert args.soak_minutes == 0 or args.soak_minutes * 60 >= benchmark.MIN_WINDOW_S
    assert args.soak_minutes > 0 or args.pairs > 0
    assert args.window >= benchmark.MIN_WINDOW_S
    assert not args.bare_soak or args.soak_minutes > 0
    defaults = benchmark.QUICK if quick else benchmark.FULL
    assert args.soak_minutes == (float(soak) if soak else defaults["soak_minutes"])
    assert args.pairs == (int(pairs) if pairs else defaults["pairs"])


@pytest.mark.parametrize(("argv", "words"), [
    (["--soak-minutes", "0", "--pairs", "0"], "nothing to measure"),
    (["--soak-minutes", "-1"], "minutes >= 0"),
    (["--soak-minutes", "nan"], "minutes >= 0"),
    (["--pairs", "1.5"], "whole number"),
    (["--window", "0"], "seconds >= 1"),
    (["--soak-minutes", "0", "--bare-soak"], "--bare-soak"),
])
def test_what_cannot_run_is_refused_naming_the_option(benchmark, capsys, argv, words):
    with pytest.raises(SystemExit) as refused:
        benchmark.arguments(argv)
    assert refused.value.code == 2 and words in capsys.readouterr().err


def test_ratios_without_a_baseline_are_not_a_division_by_zero(benchmark):
    assert benchmark.spread([benchmark.ratio(2.0, 0.0)]) == "- (no baseline above 0)"
    assert benchmark.spread([benchmark.ratio(2.0, 1.0), benchmark.ratio(1.0, 0.0)]) == "2.00x (2.00-2.00)"


@pytest.mark.slow
@pytest.mark.skipif(os.geteuid() != 0, reason="the benchmark needs root (SCHED_FIFO, raw sockets, namespaces)")
def test_without_the_soak_the_pairs_run_to_their_end():
    done = subprocess.run([sys.executable, str(BENCHMARKS / "ethercat.py"), "--soak-minutes", "0", "--pairs", "1",
                           "--window", "1"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "Traceback" not in done.stderr and "soak (" not in done.stdout
    assert "pair  1:" in done.stdout and "exchange p50 plem/bare" in done.stdout, done.stdout
