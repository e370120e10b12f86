"""Time parameterisation: how long re-timed trajectories take, against bounds and a uniform scaling, and its cost.

Usage: python benchmarks/retiming.py [--repeats 5]

The trajectories ROS users send, on the built-in Indy7's limits (1 kHz), each through
`plem.planning.fit_to_limits` from rest:
  one point       positions only, 0.5 s for 1 rad on every joint (too fast for the limits);
  trapezoid       MoveIt-style: 21 points at 10 Hz with velocities and accelerations, a = 0.5 rad/s²;
  ramp N          N positions-only points of a smooth rest-to-rest ramp in 1 s (too fast);
  sine N          N positions-only points of a sine that starts and ends moving, 0.01 s apart (too fast).
Figures per trajectory:
  asked           its last time_from_start;
  plem            the duration plem runs it in;
  uniform         baseline from the same run: the same smoothed spline scaled uniformly (one time factor for all);
  bound           a lower bound of any motion from rest through the points in order to rest: the larger of
                  Σ over segments of max over joints of |Δq|/v_max and ruckig's time-optimal motion straight to
                  the last point within the velocity, acceleration and jerk limits; and plem over it;
  µs/point        time to parameterise, per point (median of --repeats).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import plem.planning.retiming as retiming
from plem.control.limits import ArmLimits
from plem.control.motion import plan_point_to_point
from plem.control.trajectory import JointTrajectory, TrajectoryPoint
from plem.description.validate import validate_package

NAMES = tuple(f"joint{i}" for i in range(6))
CYCLE = 0.001
SPREAD = np.linspace(0.2, 1.5, 6)


def trapezoid(time_s: float, duration: float = 2.0, acceleration: float = 0.5, blend: float = 0.5) -> tuple[float, ...]:
    top = acceleration * blend
    if time_s < blend:
        return 0.5 * acceleration * time_s**2, acceleration * time_s, acceleration
    if time_s < duration - blend:
        return 0.5 * top * blend + top * (time_s - blend), top, 0.0
    left = max(duration - time_s, 0.0)
    return top * (duration - blend) - 0.5 * acceleration * left**2, acceleration * left, -acceleration if left else 0.0


def cases() -> dict[str, list[TrajectoryPoint]]:
    found = {"one point": [TrajectoryPoint((1.0,) * 6, 0.5)]}
    found["trapezoid"] = [TrajectoryPoint((p,) * 6, 0.1 * k, (v,) * 6, (a if k < 20 else 0.0,) * 6)
                          for k in range(1, 21) for p, v, a in [trapezoid(0.1 * k)]]
    for n in (50, 500, 5000):
        u = np.arange(1, n + 1) / n
        ramp = 10 * u**3 - 15 * u**4 + 6 * u**5
        found[f"ramp {n}"] = [TrajectoryPoint(tuple(SPREAD * r), float(t)) for r, t in zip(ramp, u, strict=True)]
    for n in (100, 1000):
        found[f"sine {n}"] = [TrajectoryPoint(tuple(0.5 * np.sin(SPREAD) * np.sin(6 * k / n)), 0.01 * k)
                              for k in range(1, n + 1)]
    return found


def lower_bound(points: list[TrajectoryPoint], limits: ArmLimits) -> float:
    """No motion from rest through the points in order to rest is shorter than either bound."""
    positions = np.array([np.zeros(6)] + [p.positions for p in points])
    through = float((np.abs(np.diff(positions, axis=0)) / limits.max_velocity).max(axis=1).sum())
    zero = np.zeros(6)
    direct = plan_point_to_point(limits, (zero, zero, zero), positions[-1]).duration
    return max(through, direct)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    limits = ArmLimits.from_joint_limits(validate_package("indy7_description").limits, NAMES)
    start = (np.zeros(6), np.zeros(6), np.zeros(6))
    print(f"{'trajectory':<12} {'asked s':>8} {'plem s':>8} {'uniform s':>10} {'plem/unif':>9} {'bound s':>8} "
          f"{'plem/bound':>10} {'µs/point':>9}  how")
    for name, points in cases().items():
        trajectory = JointTrajectory(NAMES, tuple(points))
        times = []
        for _ in range(args.repeats):
            began = time.perf_counter()
            timed = retiming.fit_to_limits(trajectory, limits, start, CYCLE)
            times.append(time.perf_counter() - began)
        retiming.PACINGS = (False,)  # uniform scaling only
        try:
            uniform = retiming.fit_to_limits(trajectory, limits, start, CYCLE)
        finally:
            retiming.PACINGS = (False, True)
        bound = lower_bound(points, limits)
        print(f"{name:<12} {timed.requested_s:8.3f} {timed.motion.duration:8.3f} {uniform.motion.duration:10.3f} "
              f"{timed.motion.duration / uniform.motion.duration:9.2f} {bound:8.3f} "
              f"{timed.motion.duration / bound:10.2f} {statistics.median(times) / len(points) * 1e6:9.0f}  "
              f"{timed.change.split(' to stay')[0] or 'as sent'}")


if __name__ == "__main__":
    main()
