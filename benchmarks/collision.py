"""Collision checks per second: plem's CollisionChecker.is_free against bare pinocchio on the same shapes and pairs.

Usage: python benchmarks/collision.py [--configurations 20000] [--rounds 5] [--quick]

Arms: the built-in Indy7 v2 (cylinders), UR5 and Franka Panda from example-robot-data (meshes; the Panda's two
finger joints locked, a 7-axis arm), each with a 1.2 × 0.8 × 0.05 m table under it (top 5 mm below the base).
The same uniformly random configurations within the joint limits go to both sides:
  plem       CollisionChecker.is_free(q) with the table in its PlanningScene (coal's AABB-tree broad phase,
             then the exact test of the pairs whose boxes overlap; first collision stops it);
  bare       pin.computeCollisions(model, data, geometry, geometry_data, q, True) on a geometry model built
             here with pin.buildGeomFromUrdfString plus the table, holding the same pairs (robot links on
             different, non-adjacent bodies and not disabled by the SRDF; the table with every link), pinocchio's
             default collision requests;
  agree      share of configurations where both give the same answer; free is the share collision-free.
Each round times every configuration on one side, then on the other (A, B, A, B ...); a side's figure is the
median over the rounds. --quick: 1000 configurations, 2 rounds (a smoke run).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from plem.description.model import parse_srdf
from plem.description.validate import validate_package
from plem.planning.collision import CollisionChecker
from plem.planning.poses import Pose
from plem.planning.scene import Box, PlanningScene, SceneObject

TABLE_SIZE = (1.2, 0.8, 0.05)
TABLE_AT = (0.5, 0.0, -0.03)
ROBOTS = "share/example-robot-data/robots"
PANDA_FINGERS = ("panda_finger_joint1", "panda_finger_joint2")


@dataclass(frozen=True)
class Arm:
    """What both sides are built from."""

    name: str
    model: pin.Model
    urdf: str
    disabled: list[tuple[str, str]]
    package_dirs: list[str]


def arms(prefix: Path) -> list[Arm]:
    report = validate_package("indy7_v2_description")
    assert report.urdf_xml is not None and report.srdf is not None
    found = [Arm("indy7 (primitives)", pin.buildModelFromXML(report.urdf_xml), report.urdf_xml,
                 [(a, b) for a, b, _ in report.srdf.disabled_collisions], [])]
    for name, urdf, srdf in (("ur5 (meshes)", "ur_description/urdf/ur5_robot.urdf", "ur_description/srdf/ur5.srdf"),
                             ("panda (meshes)", "panda_description/urdf/panda.urdf",
                              "panda_description/srdf/panda.srdf")):
        text = (prefix / ROBOTS / urdf).read_text()
        model = pin.buildModelFromXML(text)
        if name.startswith("panda"):
            model = pin.buildReducedModel(model, [model.getJointId(j) for j in PANDA_FINGERS], pin.neutral(model))
        pairs = parse_srdf((prefix / ROBOTS / srdf).read_text(), Path(srdf)).disabled_collisions
        found.append(Arm(name, model, text, [(a, b) for a, b, _ in pairs], [str(prefix / "share")]))
    return found


def bare_geometry(arm: Arm) -> pin.GeometryModel:
    """The arm's collision shapes and the table, with the pairs a checker of the SRDF's rules would test."""
    geometry = pin.buildGeomFromUrdfString(arm.model, arm.urdf, pin.COLLISION, package_dirs=arm.package_dirs)
    robot = geometry.ngeoms
    geometry.addGeometryObject(pin.GeometryObject("table", 0, 0, pin.SE3(np.eye(3), np.array(TABLE_AT)),
                                                  coal.Box(*TABLE_SIZE)))
    shapes = geometry.geometryObjects
    link = [arm.model.frames[shape.parentFrame].name for shape in shapes]
    body = [shape.parentJoint for shape in shapes]
    parents = arm.model.parents
    disabled = {frozenset(pair) for pair in arm.disabled}
    for i in range(robot):
        for j in range(i + 1, robot):
            if (body[i] != body[j] and parents[body[i]] != body[j] and parents[body[j]] != body[i]
                    and frozenset((link[i], link[j])) not in disabled):
                geometry.addCollisionPair(pin.CollisionPair(i, j))
        geometry.addCollisionPair(pin.CollisionPair(i, robot))
    return geometry


def bare_check(model: pin.Model, geometry: pin.GeometryModel) -> Callable[[np.ndarray], bool]:
    """Whether `q` is collision-free by pinocchio's loop over every pair, stopping at the first collision."""
    data, geometry_data = model.createData(), pin.GeometryData(geometry)

    def is_free(q: np.ndarray) -> bool:
        return not pin.computeCollisions(model, data, geometry, geometry_data, q, True)
    return is_free


def timed(check: Callable[[np.ndarray], bool], configurations: np.ndarray) -> tuple[float, list[bool]]:
    began = time.perf_counter()
    answers = [check(q) for q in configurations]
    return time.perf_counter() - began, answers


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configurations", type=int, default=20000)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="1000 configurations, 2 rounds: a smoke run")
    args = parser.parse_args()
    if args.quick:
        args.configurations, args.rounds = 1000, 2
    prefix = Path(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix"))
    os.environ["AMENT_PREFIX_PATH"] = str(prefix)  # example-robot-data's package:// URIs resolve for plem
    rng = np.random.default_rng(1)
    print(f"{'arm':<20} {'pairs':>5} {'free':>6} {'plem checks/s':>14} {'bare checks/s':>14} {'plem/bare':>9} "
          f"{'agree':>7}")
    for arm in arms(prefix):
        checker = CollisionChecker(arm.model, arm.urdf, arm.disabled)
        checker.set_scene(PlanningScene([SceneObject("table", Box(TABLE_SIZE), Pose(TABLE_AT))]))
        geometry = bare_geometry(arm)
        bare = bare_check(arm.model, geometry)
        configurations = rng.uniform(arm.model.lowerPositionLimit, arm.model.upperPositionLimit,
                                     (args.configurations, arm.model.nq))
        plem_times, bare_times = [], []
        for _ in range(args.rounds):
            elapsed, plem_free = timed(checker.is_free, configurations)
            plem_times.append(elapsed)
            elapsed, bare_free = timed(bare, configurations)
            bare_times.append(elapsed)
        plem_rate = args.configurations / statistics.median(plem_times)
        bare_rate = args.configurations / statistics.median(bare_times)
        agree = np.mean(np.array(plem_free) == np.array(bare_free))
        print(f"{arm.name:<20} {len(geometry.collisionPairs):>5} {np.mean(plem_free):>6.1%} {plem_rate:>14,.0f} "
              f"{bare_rate:>14,.0f} {plem_rate / bare_rate:>9.2f} {agree:>7.2%}")


if __name__ == "__main__":
    main()
