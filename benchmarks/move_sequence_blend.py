"""`move_sequence` with blends against the same points stopping at each: total time and the limits kept.

Usage: python benchmarks/move_sequence_blend.py [--rounds 3] [--blend 0.07]

On the built-in Indy7 (1 kHz, its own limits, the tool limits' defaults), the planner plans a sequence of 10
straight moves (Linear items) from home through a meander of points 15 cm apart at right angles in a horizontal
plane (a raster, as gluing or scanning paths are), twice per round, alternating: every corner with a blend
radius of --blend metres, and every corner at blend 0 (the arm stops there). For each it prints the planned
duration and planning time, and checks the motion the RT driver runs for it, every 1 ms cycle: run as sent
(never re-timed), within every position, velocity, acceleration and jerk limit, the tool within its speed
limit, and (blended) never at rest between the first point and the end. The figure: blended total time over
stopping total time (target ≤ 0.7), per round and its median. It waits while the load average is above 3
(other work slows the planning times, not the motion times).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from plem.control.limits import ArmLimits
from plem.description.validate import validate_package
from plem.planning.goals import Plan
from plem.planning.planner import Planner
from plem.planning.poses import Pose
from plem.planning.retiming import fit_to_limits
from plem.planning.sequence import Linear, ToolLimits

CYCLE_S = 0.001
DOWN = (0.0, 1.0, 0.0, 0.0)
#: Ten points, a meander of right-angled corners 15 cm apart in the plane z = 0.45 m below the Indy7's home.
POINTS = [(0.35 + 0.15 * (((k + 1) // 2) % 2), -0.35 + 0.15 * (k // 2), 0.45) for k in range(10)]


def checked(planner: Planner, limits: ArmLimits, plan: Plan, blended: bool) -> str:
    """The motion the RT driver runs for the plan, every cycle, against every limit; what was found."""
    start = np.array(plan.trajectory.points[0].positions)
    rest = np.zeros(len(start))
    timed = fit_to_limits(plan.trajectory, limits, (start, rest, rest), CYCLE_S)
    assert timed.change == "", f"re-timed: {timed.note()}"
    states = np.array([np.stack(timed.motion.state_at(float(t)))
                       for t in np.arange(0.0, timed.motion.duration + CYCLE_S, CYCLE_S)])
    q, v, a = states[:, 0], states[:, 1], states[:, 2]
    jerk = np.abs(np.diff(a, axis=0)) / CYCLE_S
    shares = [float((np.abs(v) / limits.max_velocity).max()), float((np.abs(a) / limits.max_acceleration).max()),
              float((jerk / limits.max_jerk).max())]
    assert np.all(q >= limits.min_position) and np.all(q <= limits.max_position)
    assert max(shares) <= 1.0 + 1e-6, shares
    tip = planner.group().tip_link
    tool = np.array([planner.fk(row, [tip])[tip].position for row in q[::5]])
    speed = np.linalg.norm(np.diff(tool, axis=0), axis=1) / (5 * CYCLE_S)
    assert speed.max() <= ToolLimits().max_trans_vel * 1.01, speed.max()
    moving = np.linalg.norm(v, axis=1)
    first_point = int(np.argmin(np.linalg.norm(tool - np.array(POINTS[0]), axis=1))) * 5
    slowest = float(moving[first_point + 200:-200].min())
    if blended:
        assert slowest > 0.0, "the arm stopped between its start and its end"
    return (f"peak v {shares[0]:.0%} a {shares[1]:.0%} j {shares[2]:.0%} of the limits, tool {speed.max():.3f} m/s, "
            f"slowest joint speed between the first point and the end {slowest:.3f} rad/s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--blend", type=float, default=0.07)
    args = parser.parse_args()
    while os.getloadavg()[0] > 3.0:
        print(f"load average {os.getloadavg()[0]:.1f} > 3: waiting")
        time.sleep(30)
    report = validate_package("indy7_v2_description")
    assert report.urdf is not None
    names = tuple(joint.name for joint in report.urdf.actuated_joints)
    limits = ArmLimits.from_joint_limits(report.limits, names)
    planner = Planner.for_package(report, names, limits, CYCLE_S)
    home = planner.named_states["home"]
    ratios = []
    for round_ in range(args.rounds):
        durations = {}
        for blend in ((args.blend, 0.0) if round_ % 2 == 0 else (0.0, args.blend)):
            items = [Linear(Pose(point, DOWN), blend=blend if k < len(POINTS) - 1 else 0.0)
                     for k, point in enumerate(POINTS)]
            plan = planner.sequence(home, items)
            found = checked(planner, limits, plan, blend > 0.0)
            durations[blend] = plan.duration_s
            print(f"round {round_ + 1}  blend {blend:.3f} m: {plan.duration_s:.3f} s motion, planned in "
                  f"{plan.planning_time_s:.2f} s; {found}")
        ratios.append(durations[args.blend] / durations[0.0])
        print(f"round {round_ + 1}  blended / stopping = {ratios[-1]:.3f}")
    print(f"median blended / stopping over {args.rounds} rounds: {statistics.median(ratios):.3f} (target <= 0.7)")


if __name__ == "__main__":
    main()
