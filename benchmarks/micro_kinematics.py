"""Cost of plem's per-cycle kinematics and motion sampling against the bare pinocchio and ruckig calls.

Usage: python benchmarks/micro_kinematics.py [--rounds N] [--calls N]

Three pairs on the 7-DOF Indy RP2 v2 (built-in description; both sides use the same pinocchio model and data):
  forward kinematics  ArmDynamics.forward_kinematics(q)
                      vs pin.framesForwardKinematics(model, data, q); data.oMf[tip]
  Jacobian            ArmDynamics.jacobian(q)
                      vs pin.computeFrameJacobian(model, data, q, tip, pin.LOCAL_WORLD_ALIGNED)
  ruckig step         RuckigMotion.sample(t, out), mid-motion
                      vs trajectory.at_time(t) on the same ruckig Trajectory
Each round times `calls` back-to-back calls of one side, then of the other (A, B, A, B ...); the figure of a
side is the median over the rounds of the time per call. The Python `for` loop around the calls (a few tens of ns)
is in both sides. Target: plem ≤ 1.5× the bare call.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from ruckig import InputParameter, Result, Ruckig, Trajectory

from plem.control.kinematics import ArmDynamics
from plem.control.limits import ArmLimits
from plem.control.motion import RuckigMotion
from plem.description.validate import Stage, require_valid
from plem.robot import IndyRP2V2

TARGET_RATIO = 1.5
WARMUP_ROUNDS = 20
PACKAGE = IndyRP2V2.MODEL.description_package
JOINTS = IndyRP2V2.MODEL.joint_names

TimedLoop = Callable[[int], int]  # runs the call n times, returns elapsed ns


@dataclass(frozen=True)
class MicroResult:
    """Median time per call of plem's call and of the bare call it wraps, in microseconds."""

    name: str
    plem_us: float
    bare_us: float

    @property
    def ratio(self) -> float:
        return self.plem_us / self.bare_us

    @property
    def met(self) -> bool:
        return self.ratio <= TARGET_RATIO


def _kinematics_loops(dynamics: ArmDynamics, q: np.ndarray) -> dict[str, tuple[TimedLoop, TimedLoop]]:
    model, data = dynamics.model, dynamics.data
    tip = model.getFrameId(dynamics.tip_frame)
    frames_fk, frame_jacobian = pin.framesForwardKinematics, pin.computeFrameJacobian
    world_aligned = pin.LOCAL_WORLD_ALIGNED
    forward_kinematics, jacobian = dynamics.forward_kinematics, dynamics.jacobian

    def plem_fk(n: int) -> int:
        start = time.perf_counter_ns()
        for _ in range(n):
            forward_kinematics(q)
        return time.perf_counter_ns() - start

    def bare_fk(n: int) -> int:
        start = time.perf_counter_ns()
        for _ in range(n):
            frames_fk(model, data, q)
            data.oMf[tip]
        return time.perf_counter_ns() - start

    def plem_jacobian(n: int) -> int:
        start = time.perf_counter_ns()
        for _ in range(n):
            jacobian(q)
        return time.perf_counter_ns() - start

    def bare_jacobian(n: int) -> int:
        start = time.perf_counter_ns()
        for _ in range(n):
            frame_jacobian(model, data, q, tip, world_aligned)
        return time.perf_counter_ns() - start

    return {"forward kinematics": (plem_fk, bare_fk), "Jacobian": (plem_jacobian, bare_jacobian)}


def _motion(limits: ArmLimits, target: np.ndarray) -> Trajectory:
    """A time-optimal ruckig trajectory from rest at zero to rest at `target`, planned with the bare API."""
    parameters = InputParameter(limits.dof)
    parameters.current_position = [0.0] * limits.dof
    parameters.current_velocity = [0.0] * limits.dof
    parameters.current_acceleration = [0.0] * limits.dof
    parameters.target_position = target.tolist()
    parameters.max_velocity = limits.max_velocity.tolist()
    parameters.max_acceleration = limits.max_acceleration.tolist()
    parameters.max_jerk = limits.max_jerk.tolist()
    trajectory = Trajectory(limits.dof)
    result = Ruckig(limits.dof).calculate(parameters, trajectory)
    if result not in (Result.Working, Result.Finished):
        raise SystemExit(f"ruckig could not plan the benchmark motion: {result.name}")
    return trajectory


def _sampling_loops(trajectory: Trajectory) -> tuple[TimedLoop, TimedLoop]:
    motion = RuckigMotion(trajectory)
    t = trajectory.duration / 2
    out = np.zeros((3, trajectory.degrees_of_freedom))
    sample, at_time = motion.sample, trajectory.at_time

    def plem_sample(n: int) -> int:
        start = time.perf_counter_ns()
        for _ in range(n):
            sample(t, out)
        return time.perf_counter_ns() - start

    def bare_at_time(n: int) -> int:
        start = time.perf_counter_ns()
        for _ in range(n):
            at_time(t)
        return time.perf_counter_ns() - start

    return plem_sample, bare_at_time


def measure(rounds: int, calls: int) -> list[MicroResult]:
    """Interleaved timing of every pair; medians over `rounds` rounds of `calls` calls per side."""
    report = require_valid(PACKAGE, stage=Stage.STARTUP)
    dynamics = ArmDynamics(report.urdf_xml, JOINTS)
    limits = ArmLimits.from_joint_limits(report.limits, JOINTS)
    q = np.linspace(-0.8, 0.8, len(JOINTS))
    pairs = _kinematics_loops(dynamics, q)
    pairs["ruckig step"] = _sampling_loops(_motion(limits, q))
    results = []
    for name, (plem_loop, bare_loop) in pairs.items():
        per_call: tuple[list[float], list[float]] = ([], [])
        for round_index in range(WARMUP_ROUNDS + rounds):
            for loop, bucket in zip((plem_loop, bare_loop), per_call, strict=False):
                elapsed = loop(calls)
                if round_index >= WARMUP_ROUNDS:
                    bucket.append(elapsed / calls / 1e3)
        results.append(MicroResult(name, statistics.median(per_call[0]), statistics.median(per_call[1])))
    return results


def print_results(results: Sequence[MicroResult], rounds: int, calls: int) -> None:
    print(f"\nPer-cycle math, 7 DOF ({PACKAGE}): {WARMUP_ROUNDS} warm-up rounds, then {rounds} interleaved rounds of "
          f"{calls} calls per side; median µs per call")
    rows = [[r.name, f"{r.plem_us:.2f}", f"{r.bare_us:.2f}", f"{r.ratio:.2f}x", "yes" if r.met else "NO"]
            for r in results]
    headers = ["call", "plem", "bare pin/ruckig", "ratio", f"<= {TARGET_RATIO}x"]
    widths = [max(len(cell) for cell in column) for column in zip(headers, *rows, strict=False)]
    for line in (headers, ["-" * width for width in widths], *rows):
        print("  ".join(cell.ljust(width) for cell, width in zip(line, widths, strict=False)).rstrip())


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=300, help="timed rounds per side")
    parser.add_argument("--calls", type=int, default=300, help="calls per round")
    args = parser.parse_args(argv)
    results = measure(args.rounds, args.calls)
    print_results(results, args.rounds, args.calls)
    print(f"target plem <= {TARGET_RATIO}x bare: {'MET' if all(r.met for r in results) else 'NOT MET'}")


if __name__ == "__main__":
    main()
