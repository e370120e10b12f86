"""plem's EtherCAT master (the core's, SOEM v1.4.0) on the virtual network, against a bare C SOEM loop on the same
emulator and cyclictest.

Usage: python benchmarks/ethercat.py [--soak-minutes 10] [--pairs 15] [--window 8] [--quick] [--bare-soak]
Needs root (SCHED_FIFO, raw sockets, network namespaces) and gcc. Installs Debian's rt-tests when `cyclictest` is
missing. --quick: a 1-minute soak and 3 pairs of 3 s windows (a smoke run); options given as well take precedence.
--soak-minutes 0 leaves the soak out, --pairs 0 the pairs; a window lasts at least 1 s (cyclictest measures whole
seconds). The full run takes about 10 + 15 x (3 x 8 s + start-up) = 20 minutes.

What runs:
  network   one `plem ethercat simulate robot_type:=indy7_v2 master_index:=60` for the whole run: six emulated
            CiA402 drives (SCHED_FIFO 90) moving the simulated Indy7 v2 behind plemec60.
  soak      `plem launch bus:=ethercat eth_interface:=plemec60 robot_type:=indy7_v2 bridge:=false record:=false`
            (RT driver at 1 kHz, the core's thread at SCHED_FIFO 98), hold, then trajectories for --soak-minutes:
            move_joints between zero and POSE at half speed, one after the other. Figures over the soak (driver
            statistics after minus before, wake-up latency of every cycle from the rt_raw ring): frames lost,
            working-counter errors, faults, the exchange (the time a cycle spends in SOEM's receive of last
            cycle's answer and its send of the next frame) p50/p99/max, wake-up p99/p99.9, compute p99 (the
            cycle without the exchange), and the emulator's CPU (% of one core). With --bare-soak the bare loop
            below then runs as long on the same network, for its bad cycles over the same span.
  pairs     --pairs times, the order rotating: plem, bare, cyclictest, each for --window s.
              plem        a fresh launch as in the soak, a trajectory running; its exchange and wake-up figures.
              bare        benchmarks/bare_soem.c, compiled here against third_party/soem: SOEM's red_test shape in
                          C, bringing the segment up with plem's PDO assignment, then at SCHED_FIFO 98 and 1 kHz:
                          absolute clock_nanosleep, receive last cycle's answer (500 µs at most, as plem), enable
                          the drives holding where they are, send.
              cyclictest  cyclictest -m -p98 --policy=fifo -t1 -i1000 -D<window> (benchmarks/loop_latency.py).
            Ratios within each pair: plem exchange p50 and p99 / bare's; plem wake-up p99 / cyclictest's.
            Reported: the median over the pairs with the spread (min-max).
Targets: soak 0 lost frames, 0 faults; compute p99 <= 20 µs; exchange p99 ratio <= 1.1; wake-up p99 ratio <= 1.1.
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from plem.bridge import connect
from plem.fieldbus.ethercat import objects

import launching
import loop_latency

INDEX = 60
INTERFACE = f"plemec{INDEX}"
POSE = [0.4, -0.3, 0.3, 0.5, -0.4, 0.5]

BARE_SOURCE = Path(__file__).with_name("bare_soem.c")
SOEM = Path(__file__).resolve().parent.parent / "third_party" / "soem"


def build_bare(directory: Path) -> Path:
    """bare_soem.c compiled against the vendored SOEM, as SOEM's own samples are built."""
    sources = [*SOEM.glob("soem/*.c"), SOEM / "osal/linux/osal.c", *SOEM.glob("oshw/linux/*.c")]
    includes = [f"-I{SOEM / d}" for d in ("soem", "osal", "osal/linux", "oshw/linux")]
    program = directory / "bare_soem"
    subprocess.run(["gcc", "-O2", "-w", *includes, str(BARE_SOURCE), *map(str, sources), "-lpthread", "-lrt",
                    "-o", str(program)], check=True)
    return program


def start_network(env: dict[str, str], log: Path, children: list[subprocess.Popen]) -> subprocess.Popen:
    """`plem ethercat simulate` of the Indy7 v2, returned once it serves."""
    output = log.open("w")
    process = subprocess.Popen([sys.executable, "-m", "plem.cli", "ethercat", "simulate", "robot_type:=indy7_v2",
                                f"master_index:={INDEX}"], stdout=output, stderr=subprocess.STDOUT, text=True,
                               env=env, start_new_session=True)
    children.append(process)
    deadline = time.monotonic() + 60
    while f"behind {INTERFACE}" not in log.read_text():
        if process.poll() is not None or time.monotonic() > deadline:
            raise SystemExit(f"the virtual network did not start:\n{log.read_text()}")
        time.sleep(0.1)
    return process


def moving(client, seconds: float) -> tuple[np.ndarray, int]:
    """Keep a trajectory running while the loop's wake-up latencies of `seconds` are drained."""
    latencies: list[np.ndarray] = []
    dropped = 0
    end = time.monotonic() + seconds
    target = POSE
    while (left := end - time.monotonic()) > 0:
        handle = client.move_joints(target, speed_scale=0.5)
        window, lost = launching.drain_loop(client, min(left, 2.0))
        latencies.append(window)
        dropped += lost
        handle.wait(60)
        target = [0.0] * 6 if target is POSE else POSE
    return np.concatenate(latencies), dropped


def plem_window(env: dict[str, str], directory: Path, children: list[subprocess.Popen], seconds: float) -> dict:
    """One launch on the virtual network, holding with a trajectory running for `seconds`: its figures."""
    robot_id = f"bench_ec_{secrets.token_hex(3)}"
    started = launching.launch(robot_id, env, directory / f"{robot_id}.log", children, bridge=False, record=False,
                               bus="ethercat", eth_interface=INTERFACE, master_index=INDEX, robot_type="indy7_v2")
    try:
        with connect(robot_id) as client:
            client.set_mode("hold")
            before = stats_after(client, time.monotonic_ns())
            latency, dropped = moving(client, seconds)
            after = stats_after(client, time.monotonic_ns())
    finally:
        launching.stop(started.process)
        children.remove(started.process)
    bus = after["bus"]
    return {"lost": bus["lost_frames"] - before["bus"]["lost_frames"],
            "wkc_errors": bus["working_counter_errors"] - before["bus"]["working_counter_errors"],
            "exchange_p50": bus["exchange"]["p50_us"], "exchange_p99": bus["exchange"]["p99_us"],
            "exchange_max": bus["exchange"]["max_us"], "exchange_samples": bus["exchange"]["samples"],
            "latency_p99": float(np.percentile(latency, 99)), "latency_p999": float(np.percentile(latency, 99.9)),
            "compute_p99": after["compute"]["p99_us"], "cycles": int(latency.size),
            "ring_dropped": dropped, "overruns": after["overruns"] - before["overruns"],
            "fault": after["fault_reason"]}


def stats_after(client, monotonic_ns: int) -> dict:
    """The driver's first statistics record written after `monotonic_ns`."""
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        stats = client.stats()
        if stats is not None and stats["monotonic_ns"] > monotonic_ns:
            return stats
        time.sleep(0.02)
    raise SystemExit("the driver published no statistics")


def bare_window(program: Path, seconds: float) -> dict:
    mappings = [hex(e.mapping) for e in objects.RX_ENTRIES] + ["--"] + [hex(e.mapping) for e in objects.TX_ENTRIES]
    done = subprocess.run([str(program), INTERFACE, str(seconds), *mappings], capture_output=True, text=True,
                          timeout=seconds + 60)
    if done.returncode != 0:
        raise SystemExit(f"the bare SOEM loop failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def ratio(value: float, baseline: float) -> float:
    """value / baseline, NaN without a baseline (a figure that measured 0)."""
    return value / baseline if baseline else float("nan")


def spread(values: list[float]) -> str:
    """The median of `values` with their range, over those that could be computed."""
    known = [value for value in values if np.isfinite(value)]
    if not known:
        return "- (no baseline above 0)"
    return f"{statistics.median(known):.2f}x ({min(known):.2f}-{max(known):.2f})"


#: The full run's options, and the smoke run's (--quick); options given on the command line take precedence.
FULL = {"soak_minutes": 10.0, "pairs": 15, "window": 8.0}
QUICK = {"soak_minutes": 1.0, "pairs": 3, "window": 3.0}
MIN_WINDOW_S = 1.0


def _number(text: str, kind: type, minimum: float, meaning: str) -> float:
    """`text` as a `kind` at least `minimum`, or an argparse error saying what is accepted."""
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not {meaning}") from None
    if not np.isfinite(value) or value < minimum:
        raise argparse.ArgumentTypeError(f"{text!r} is not {meaning}")
    return value


def arguments(argv: list[str] | None = None) -> argparse.Namespace:
    """The run's options, checked: every combination accepted here runs to its end."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--soak-minutes", type=lambda t: _number(t, float, 0.0, "minutes >= 0 (0: no soak)"),
                        help=f"length of the soak, 0 for none (default {FULL['soak_minutes']:g})")
    parser.add_argument("--pairs", type=lambda t: int(_number(t, int, 0, "a whole number >= 0 (0: no pairs)")),
                        help=f"pairs of plem, bare and cyclictest windows, 0 for none (default {FULL['pairs']})")
    parser.add_argument("--window", type=lambda t: _number(t, float, MIN_WINDOW_S, f"seconds >= {MIN_WINDOW_S:g}"),
                        help=f"length of each window of a pair, s (default {FULL['window']:g})")
    parser.add_argument("--quick", action="store_true", help="a smoke run: " + ", ".join(
        f"--{name.replace('_', '-')} {value:g}" for name, value in QUICK.items()))
    parser.add_argument("--bare-soak", action="store_true", help="soak the bare C loop as long, after plem's")
    args = parser.parse_args(argv)
    for name, value in (QUICK if args.quick else FULL).items():
        if getattr(args, name) is None:
            setattr(args, name, value)
    if args.soak_minutes > 0 and args.soak_minutes * 60 < MIN_WINDOW_S:
        parser.error(f"--soak-minutes {args.soak_minutes:g} is shorter than a second: give 0 (no soak) or more")
    if args.soak_minutes == 0 and args.pairs == 0:
        parser.error("nothing to measure with --soak-minutes 0 and --pairs 0: give either a soak or pairs")
    if args.bare_soak and args.soak_minutes == 0:
        parser.error("--bare-soak soaks the bare loop as long as --soak-minutes: give the soak's minutes")
    return args


def soak_run(env: dict[str, str], directory: Path, children: list[subprocess.Popen], network: subprocess.Popen,
             minutes: float) -> None:
    """plem's soak on the running network, printed with its targets."""
    meter = launching.CpuMeter({"emulator": network.pid})
    soak = plem_window(env, directory, children, minutes * 60)
    emulator_cpu = meter.done()["emulator"]
    print(f"soak ({minutes:g} min at 1 kHz, trajectory running): {soak['cycles']} cycles, "
          f"frames lost {soak['lost']}, working-counter errors {soak['wkc_errors']}, overruns "
          f"{soak['overruns']}, fault: {soak['fault'] or 'none'}", flush=True)
    print(f"  exchange p50 {soak['exchange_p50']:.0f} µs, p99 {soak['exchange_p99']:.0f} µs, max "
          f"{soak['exchange_max']:.0f} µs ({soak['exchange_samples']} exchanges); wake-up p99 "
          f"{soak['latency_p99']:.0f} µs, p99.9 {soak['latency_p999']:.0f} µs; compute p99 "
          f"{soak['compute_p99']:.0f} µs; emulator CPU {emulator_cpu:.0f} % of a core", flush=True)
    print(f"  target 0 lost frames, 0 faults: {launching.verdict(soak['lost'] == 0 and not soak['fault'])}; "
          f"compute p99 <= 20 µs: {launching.verdict(soak['compute_p99'] <= 20)}", flush=True)


def bare_soak_run(program: Path, minutes: float) -> None:
    """The bare C loop as long as plem's soak, on the same network, printed."""
    bare = bare_window(program, minutes * 60)
    print(f"bare soak ({minutes:g} min, holding): {bare['cycles']} cycles, bad cycles {bare['bad']}; exchange p50 "
          f"{bare['exchange_p50']:.0f} µs, p99 {bare['exchange_p99']:.0f} µs, max {bare['exchange_max']:.0f} µs; "
          f"wake-up p99 {bare['latency_p99']:.0f} µs", flush=True)


def pairs_run(env: dict[str, str], directory: Path, children: list[subprocess.Popen], bare_program: Path,
              cyclictest: str, pairs: int, window: float) -> None:
    """`pairs` rotating pairs of plem, bare and cyclictest windows, each printed, then their medians."""
    exchange50, exchange99, wake, compute = [], [], [], []
    sides = ("plem", "bare", "cyclictest")
    for pair in range(pairs):
        results: dict[str, dict] = {}
        for side in sides[pair % 3:] + sides[:pair % 3]:
            if side == "plem":
                results[side] = plem_window(env, directory, children, window)
            elif side == "bare":
                results[side] = bare_window(bare_program, window)
            else:
                run, _ = loop_latency.run_cyclictest(cyclictest, 1000, round(window))
                results[side] = {"latency_p99": float(run.latency.p99)}
        plem, bare, cyclic = results["plem"], results["bare"], results["cyclictest"]
        exchange50.append(ratio(plem["exchange_p50"], bare["exchange_p50"]))
        exchange99.append(ratio(plem["exchange_p99"], bare["exchange_p99"]))
        wake.append(ratio(plem["latency_p99"], cyclic["latency_p99"]))
        compute.append(plem["compute_p99"])
        print(f"pair {pair + 1:2d}: exchange p50 plem {plem['exchange_p50']:.1f} / bare "
              f"{bare['exchange_p50']:.1f} µs, p99 {plem['exchange_p99']:.1f} / {bare['exchange_p99']:.1f} µs "
              f"(max {plem['exchange_max']:.0f} / {bare['exchange_max']:.0f}); wake-up p99 plem "
              f"{plem['latency_p99']:.0f} / cyclictest {cyclic['latency_p99']:.0f} µs; compute p99 "
              f"{plem['compute_p99']:.0f} µs; bad cycles plem {plem['lost'] + plem['wkc_errors']} bare "
              f"{bare['bad']}", flush=True)
    print(f"exchange p50 plem/bare: {spread(exchange50)}; p99: {spread(exchange99)}; target <= 1.1x: "
          f"{launching.verdict(_median(exchange99) <= 1.1)}")
    print(f"wake-up p99 plem/cyclictest: {spread(wake)}; target <= 1.1x: {launching.verdict(_median(wake) <= 1.1)}")
    print(f"compute p99 (without the exchange): median {statistics.median(compute):.0f} µs "
          f"({min(compute):.0f}-{max(compute):.0f}); target <= 20 µs: "
          f"{launching.verdict(statistics.median(compute) <= 20)}")


def _median(ratios: list[float]) -> float:
    """The median of the ratios that could be computed (NaN, which meets no target, when none could)."""
    known = [value for value in ratios if np.isfinite(value)]
    return statistics.median(known) if known else float("nan")


def main(argv: list[str] | None = None) -> int:
    """Run what the options ask for; 0 when it ran to the end, 130 when interrupted (Ctrl-C)."""
    args = arguments(argv)
    machine = launching.begin_run()
    cyclictest = loop_latency.ensure_cyclictest() if args.pairs else ""
    print(f"machine: {machine}", flush=True)
    children: list[subprocess.Popen] = []
    with tempfile.TemporaryDirectory(prefix="plem-bench-ethercat-") as tmp:
        directory = Path(tmp)
        env = {**os.environ, "PLEM_HOME": str(directory / "home")}
        try:
            network = start_network(env, directory / "network.log", children)
            if args.soak_minutes:
                soak_run(env, directory, children, network, args.soak_minutes)
            if args.bare_soak or args.pairs:
                bare_program = build_bare(directory)
                if args.bare_soak:
                    bare_soak_run(bare_program, args.soak_minutes)
                if args.pairs:
                    pairs_run(env, directory, children, bare_program, cyclictest, args.pairs, args.window)
        except KeyboardInterrupt:
            print("interrupted: stopping the launches and the virtual network", flush=True)
            return 130
        finally:
            launching.stop_all(children)
    return 0


if __name__ == "__main__":
    sys.exit(main())
