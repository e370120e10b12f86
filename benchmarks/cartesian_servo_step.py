"""Cost of one Cartesian servo step against the plain differential-IK step it extends.

Usage: python benchmarks/cartesian_servo_step.py [--rounds N] [--calls N] [--max-load L]

On the Indy7 v2 (built-in description, tool link `tcp`), a twist of 0.1 m/s along x and 0.2 rad/s about z, dt 1 ms:
  plem      CartesianServo.twist_step(q, twist, dt): Jacobian, SVD, damped least squares, singularity, joint limit
            and velocity limit scaling
  baseline  pin.computeFrameJacobian(model, data, q, tool, LOCAL_WORLD_ALIGNED); q + np.linalg.pinv(J) @ twist * dt
at two poses: a working pose (smallest singular value 0.17: no slowing, the singularity check skipped) and one
near the elbow singularity (0.06: the derivative of the singular value computed too). Each round times `calls`
back-to-back calls of one side, then of the other (A, B, A, B ...); a figure is the median over the rounds of
the time per call. It refuses to run while the load average is above --max-load (timing would be the load's).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from plem.control.cartesian_servo import CartesianServo
from plem.control.kinematics import ArmDynamics
from plem.control.limits import ArmLimits
from plem.description.validate import Stage, require_valid
from plem.robot import Indy7V2

WARMUP_ROUNDS = 20
PACKAGE = Indy7V2.MODEL.description_package
JOINTS = Indy7V2.MODEL.joint_names
DT = 1e-3
TWIST = np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.2])
POSES = {"working pose": np.array([0.3, -0.3, -1.2, 0.2, -1.2, 0.2]),
         "near the elbow singularity": np.array([0.27, -0.85, -0.3, 0.2, -1.83, 0.3])}

TimedLoop = Callable[[int], int]  # runs the call n times, returns elapsed ns


def loops(servo: CartesianServo, dynamics: ArmDynamics, q: np.ndarray) -> tuple[TimedLoop, TimedLoop]:
    """The plem step and the baseline step at `q`, each as a timed loop."""
    model, data = dynamics.model, dynamics.model.createData()
    tool = model.getFrameId("tcp", pin.FrameType.BODY)
    step, frame_jacobian, pinv, aligned = servo.twist_step, pin.computeFrameJacobian, np.linalg.pinv, \
        pin.LOCAL_WORLD_ALIGNED

    def plem(n: int) -> int:
        start = time.perf_counter_ns()
        for _ in range(n):
            step(q, TWIST, DT)
        return time.perf_counter_ns() - start

    def baseline(n: int) -> int:
        start = time.perf_counter_ns()
        for _ in range(n):
            q + pinv(frame_jacobian(model, data, q, tool, aligned)) @ TWIST * DT
        return time.perf_counter_ns() - start

    return plem, baseline


def measure(rounds: int, calls: int) -> dict[str, tuple[float, float]]:
    """Median µs per call of the plem step and the baseline at each pose, interleaved."""
    report = require_valid(PACKAGE, stage=Stage.STARTUP)
    dynamics = ArmDynamics(report.urdf_xml, JOINTS, "tcp")
    servo = CartesianServo(dynamics, ArmLimits.from_joint_limits(report.limits, JOINTS))
    results = {}
    for name, q in POSES.items():
        per_call: tuple[list[float], list[float]] = ([], [])
        for round_index in range(WARMUP_ROUNDS + rounds):
            for loop, bucket in zip(loops(servo, dynamics, q), per_call, strict=True):
                elapsed = loop(calls)
                if round_index >= WARMUP_ROUNDS:
                    bucket.append(elapsed / calls / 1e3)
        results[name] = (statistics.median(per_call[0]), statistics.median(per_call[1]))
    return results


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=200, help="timed rounds per side")
    parser.add_argument("--calls", type=int, default=200, help="calls per round")
    parser.add_argument("--max-load", type=float, default=3.0, help="largest 1-minute load average to run at")
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    if load > args.max_load:
        raise SystemExit(f"load average {load:.2f} is above {args.max_load:g}: the figures would be the load's; "
                         "run again when the machine is quieter")
    results = measure(args.rounds, args.calls)
    print(f"Cartesian servo step, 6 DOF ({PACKAGE}), load average {load:.2f} at the start: {WARMUP_ROUNDS} warm-up "
          f"rounds, then {args.rounds} interleaved rounds of {args.calls} calls per side; median µs per call")
    rows = [[name, f"{plem:.1f}", f"{baseline:.1f}", f"{plem / baseline:.2f}x"]
            for name, (plem, baseline) in results.items()]
    headers = ["pose", "plem step", "baseline (computeFrameJacobian + pinv)", "ratio"]
    widths = [max(len(cell) for cell in column) for column in zip(headers, *rows, strict=True)]
    for line in (headers, ["-" * width for width in widths], *rows):
        print("  ".join(cell.ljust(width) for cell, width in zip(line, widths, strict=True)).rstrip())
    print(f"per step at 1 kHz: {max(plem for plem, _ in results.values()) / 10:.1f} % of one core at most")


if __name__ == "__main__":
    main()
