"""Motion planning on a fixed problem set: plem's planner against bare OMPL with the same validity checker.

Usage: python -m benchmarks.planning [--quick] [--generate]   (from the repository root: it wraps UR5 and Panda
with the test suite's tests/third_party.py)

Problems (benchmarks/planning_problems.json, made by --generate with a fixed seed and shipped with this
file): for each arm (indy7, indyrp2, UR5, Panda) and each scene, 18 start/goal pairs of collision-free
configurations with every link above the base's plane (the arm stands on a table) whose straight
joint-space line collides, so every problem needs a detour:
  table     a table top just below the base, and a box on it in front of the arm;
  shelf     a shelf in front: two boards and a back wall;
  passage   a wall in front with a narrow gap to pass through.
Figures per arm and scene, over the pairs:
  success       share solved within 5 s: by plem's planner layer, by bare OMPL, and by the whole plan;
  median / p95  planning time (ms): plem = `plem.planning.paths.plan_path` (RRTConnect, simplification);
                bare = the same through OMPL's SimpleSetup directly, the same validity function
                (`CollisionChecker.is_free` of an instance of its own) and check resolution, in the same run,
                alternating; ratio = plem over bare (the planner layer's overhead);
  total         plem's whole `Planner.plan` (median, ms): goal checks, planning, time parameterisation and the
                dense re-check of the timed motion;
  length        joint-space path length (rad, median);
  duration/bound  the path timed within the limits (straight lines, at rest at each corner) over the bound from
                the limits (`plem.planning.parameterisation.duration_bound`), median; ms/state: time to
                parameterise, per path state.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
from ompl import base as ob
from ompl import geometric as og

from plem.control.limits import ArmLimits
from plem.description.validate import validate_package
from plem.planning.collision import CollisionChecker
from plem.planning.goals import JointGoal, PlanOptions
from plem.planning.parameterisation import duration_bound, parameterise, planning_limits
from plem.planning.paths import CHECK_STEP, SIMPLIFY_SHARE, plan_path
from plem.planning.planner import Planner
from plem.planning.poses import Pose
from plem.planning.scene import Box, SceneObject
from tests.third_party import ARMS, data_prefix, write_package

PROBLEMS = Path(__file__).with_name("planning_problems.json")
PAIRS = 18
TIMEOUT_S = 5.0
CYCLE = 0.001
PANDA_READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)


def arms(folder: Path) -> dict[str, Planner]:
    """The four arms' planners (UR5 and Panda wrapped as description packages under `folder`)."""
    import os

    prefix = data_prefix()
    os.environ["AMENT_PREFIX_PATH"] = str(prefix)
    os.environ["PLEM_PACKAGE_PATH"] = str(folder)
    packages = {"indy7": "indy7_v2_description", "indyrp2": "indyrp2_v2_description"}
    for spec in ARMS:
        packages[spec.name] = write_package(spec, prefix, folder).spec.package
    planners = {}
    for name, package in packages.items():
        report = validate_package(package)
        assert report.urdf is not None
        joints = tuple(joint.name for joint in report.urdf.actuated_joints)
        planners[name] = Planner.for_package(report, joints, ArmLimits.from_joint_limits(report.limits, joints),
                                             CYCLE)
    return planners


def reach(planner: Planner) -> float:
    """How far the tool gets from the base, roughly: the tool's distance at the zero state, at least 0.5 m."""
    tip = planner.group().tip_link
    position = np.array(planner.fk(np.zeros(len(planner.joint_names)), [tip])[tip].position)
    return float(max(np.linalg.norm(position), 0.5))


def scenes(r: float) -> dict[str, list[SceneObject]]:
    """The three scenes, scaled to an arm's reach `r`."""
    def box(name: str, size: tuple[float, float, float], at: tuple[float, float, float]) -> SceneObject:
        return SceneObject(name, Box(size), Pose(at))

    return {
        "table": [box("table", (2 * r, 2 * r, 0.04), (0.0, 0.0, -0.03)),
                  box("crate", (0.2 * r, 0.3 * r, 0.3 * r), (0.6 * r, 0.0, 0.15 * r))],
        "shelf": [box("board_low", (0.3 * r, 0.8 * r, 0.02), (0.65 * r, 0.0, 0.3 * r)),
                  box("board_high", (0.3 * r, 0.8 * r, 0.02), (0.65 * r, 0.0, 0.7 * r)),
                  box("back", (0.02, 0.8 * r, 0.8 * r), (0.8 * r, 0.0, 0.5 * r))],
        "passage": [box("wall_left", (0.02, 0.8 * r, 1.2 * r), (0.5 * r, 0.5 * r, 0.5 * r)),
                    box("wall_right", (0.02, 0.8 * r, 1.2 * r), (0.5 * r, -0.5 * r, 0.5 * r))],
    }


def generate(planners: dict[str, Planner]) -> dict[str, object]:
    """Start/goal pairs per arm and scene: both free, the straight line between them blocked."""
    rng = np.random.default_rng(2026)
    problems: dict[str, object] = {}
    for name, planner in planners.items():
        lower, upper = planner.limits.min_position, planner.limits.max_position
        per_scene = {}
        for scene_name, objects in scenes(reach(planner)).items():
            set_scene(planner, objects)
            pairs: list[list[list[float]]] = []
            while len(pairs) < PAIRS:
                start, goal = rng.uniform(lower, upper), rng.uniform(lower, upper)
                if planner.contacts(start) or planner.contacts(goal) or under(planner, start) or under(planner, goal):
                    continue
                line = [start + (goal - start) * s for s in np.linspace(0, 1, 60)]
                if any(planner.contacts(q) for q in line):
                    pairs.append([start.tolist(), goal.tolist()])
            per_scene[scene_name] = pairs
        problems[name] = per_scene
    return problems


def under(planner: Planner, positions: np.ndarray) -> bool:
    """Whether a link is below the base's plane: under the table the arm stands on, which no path can reach."""
    links = [frame.name for frame in planner.arm.model.frames if frame.type == pin.FrameType.BODY]
    return any(pose.position[2] < 0.0 for pose in planner.fk(positions, links).values())


def set_scene(planner: Planner, objects: list[SceneObject]) -> None:
    for item in planner.scene.objects():
        planner.scene.remove(item.name)
    for item in objects:
        planner.scene.add(item)


def bare(checker: CollisionChecker, planner: Planner, start: np.ndarray, goal: np.ndarray) -> float | None:
    """Planning time (s) of RRTConnect with simplification straight through OMPL, or None when it fails."""
    dof = len(start)
    q = np.empty(dof)
    order = planner.arm.model_indices

    def valid(state: ob.State) -> bool:
        for i in range(dof):
            q[order[i]] = state[i]
        return checker.is_free(q)

    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i in range(dof):
        bounds.setLow(i, float(planner.limits.min_position[i]))
        bounds.setHigh(i, float(planner.limits.max_position[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    setup.setStateValidityChecker(valid)
    setup.getSpaceInformation().setStateValidityCheckingResolution(CHECK_STEP / space.getMaximumExtent())
    s, g = space.allocState(), space.allocState()
    for i in range(dof):
        s[i], g[i] = float(start[i]), float(goal[i])
    setup.setStartAndGoalStates(s, g)
    setup.setPlanner(og.RRTConnect(setup.getSpaceInformation()))
    began = time.perf_counter()
    setup.solve(TIMEOUT_S)
    if not setup.haveExactSolutionPath():
        return None
    setup.simplifySolution(max(TIMEOUT_S - (time.perf_counter() - began), 0.0) * SIMPLIFY_SHARE)
    return time.perf_counter() - began


def layer(planner: Planner, start: np.ndarray, goal: np.ndarray) -> tuple[float, np.ndarray] | None:
    """Planning time (s) of plem's path layer on the same problem (the planner's own validity function), and the
    path's states."""
    is_free = planner.collisions.is_free
    order = planner.arm.model_indices
    q = np.empty(len(start))

    def free(values: np.ndarray) -> bool:
        q[order] = values
        return is_free(q)

    began = time.perf_counter()
    try:
        path = plan_path(planner.limits.min_position, planner.limits.max_position, free, start, [goal], "",
                         TIMEOUT_S)
    except Exception:  # noqa: BLE001 - a failure counts against the success rate
        return None
    return time.perf_counter() - began, path.states


def percentile(values: list[float], share: float) -> float:
    return float(np.percentile(values, share)) if values else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 pairs per arm and scene")
    parser.add_argument("--generate", action="store_true", help=f"write {PROBLEMS.name} anew")
    args = parser.parse_args()
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        planners = arms(Path(folder))
        if args.generate or not PROBLEMS.exists():
            PROBLEMS.write_text(json.dumps(generate(planners)))
        problems = json.loads(PROBLEMS.read_text())
        print(f"{'arm':<8} {'scene':<8} {'pairs':>5} {'success':>14} {'plem ms':>9} {'p95':>7} {'bare ms':>8} "
              f"{'p95':>7} {'ratio':>6} {'total ms':>9} {'length':>7} {'duration/bound':>15} {'ms/state':>9}")
        ratios = []
        for name, planner in planners.items():
            for scene_name, objects in scenes(reach(planner)).items():
                set_scene(planner, objects)
                checker = CollisionChecker(planner.arm.model, planner.urdf_xml, planner.disabled_pairs)
                checker.set_scene(planner.scene)
                pairs = problems[name][scene_name][: 3 if args.quick else PAIRS]
                plem_times, bare_times, totals, lengths, stretch, per_state = [], [], [], [], [], []
                for start_list, goal_list in pairs:
                    start, goal = np.array(start_list), np.array(goal_list)
                    ours = layer(planner, start, goal)
                    theirs = bare(checker, planner, start, goal)
                    if ours is not None:
                        plem_times.append(ours[0])
                        began = time.perf_counter()
                        motion = parameterise(ours[1], planning_limits(planner.limits), CYCLE, straight=True)
                        per_state.append((time.perf_counter() - began) / len(ours[1]))
                        stretch.append(motion.duration / duration_bound(ours[1], planner.limits))
                    if theirs is not None:
                        bare_times.append(theirs)
                    try:
                        plan = planner.plan(start, JointGoal(dict(zip(planner.joint_names, goal, strict=True))),
                                            PlanOptions(timeout_s=TIMEOUT_S))
                    except Exception:  # noqa: BLE001 - counted as a failure
                        continue
                    totals.append(plan.planning_time_s)
                    lengths.append(plan.path_length)
                ratio = statistics.median(plem_times) / statistics.median(bare_times)
                ratios.append(ratio)
                shares = "/".join(f"{len(found) / len(pairs):.0%}" for found in (plem_times, bare_times, totals))
                print(f"{name:<8} {scene_name:<8} {len(pairs):>5} {shares:>14} "
                      f"{statistics.median(plem_times) * 1e3:>9.1f} {percentile(plem_times, 95) * 1e3:>7.1f} "
                      f"{statistics.median(bare_times) * 1e3:>8.1f} {percentile(bare_times, 95) * 1e3:>7.1f} "
                      f"{ratio:>6.2f} {statistics.median(totals) * 1e3:>9.1f} {statistics.median(lengths):>7.2f} "
                      f"{statistics.median(stretch):>15.2f} {statistics.median(per_state) * 1e3:>9.2f}")
        print(f"planner layer over bare OMPL: median ratio {statistics.median(ratios):.2f} "
              f"({min(ratios):.2f}-{max(ratios):.2f} over arms and scenes)")


if __name__ == "__main__":
    main()
