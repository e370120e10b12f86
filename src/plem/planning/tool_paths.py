"""The geometry of a motion sequence: dense joint states along its joint, straight and circular moves, with the
corners that have a blend radius rounded off.

A joint move is a straight line in joint space. A straight or circular move is a tool path (positions along the
line or arc, the orientation by slerp from start to end), solved by IK step by step from the previous state. A
corner with a blend radius r is replaced, from where the tool enters the sphere of radius r around the corner
to where it leaves it, by a quintic Bézier curve around the corner (`_bezier`): in tool space
(positions, with the orientation by slerp) between two Cartesian moves, so the tool stays inside the sphere; in
joint space (around the corner's joint state) next to a joint move. Both join straight neighbours tangent and
without a jump of curvature, and never stop the arm.

What cannot be followed is refused, naming the item and the pose: a pose IK cannot reach (outside the
workspace or the joint limits), a configuration whose Jacobian's smallest singular value is below
SINGULAR_SIGMA (a singularity) and a joint step between neighbouring states above FLIP_STEP (a flip to another
IK branch). Nothing is cut short.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from plem.errors import MoveItCode, PlanningError
from plem.planning.cartesian import MAX_STEPS, along_line
from plem.planning.poses import Pose
from plem.planning.sequence import Circular, Item, Joint, Linear

#: Longest tool step (m, and rad of rotation at 1 rad per metre) between two states of a path.
MAX_STEP = 0.005
#: Longest joint step (rad) between two states of a joint move.
JOINT_STEP = 0.02
#: Largest joint step (rad) between two states of a Cartesian path: beyond it the IK answer flipped to another
#: branch (at MAX_STEP, 40 rad of joint motion per metre of tool travel).
FLIP_STEP = 0.2
#: Smallest singular value of the tip's Jacobian (m/rad, rad/rad) a Cartesian path may pass: below it the tool's
#: speed needs joint speeds beyond any limit (a wrist, elbow or shoulder singularity).
SINGULAR_SIGMA = 0.02
#: Where a blend's inner control points sit on each leg, as shares of the way from its end to the corner: the
#: pair that keeps the largest curvature lowest for right-angled corners (1.07/r, a circular arc's being 1/r).
BEZIER_LEG = (0.2, 0.6)
#: Cosine of the largest turn a blend may round (170°): at a corner where the tool turns back it must stop.
REVERSAL = -0.985
#: A centre this far (m) from being equidistant from an arc's start and end is refused.
RADIUS_TOLERANCE = 1e-3
#: Three points closer than this (m²) to a line span no circle.
COLLINEAR = 1e-8


@dataclass
class Sample:
    """One state of the path: joint positions (the planner's order), the tool's placement, the item it belongs to,
    whether the arm stops there and whether the tool limits apply on the step arriving at it."""

    q: np.ndarray
    tool: pin.SE3
    item: int
    stop: bool = False
    cartesian: bool = False


@dataclass(frozen=True)
class Kinematics:
    """What building a path asks of the planner: the tool's placement at q, IK from a seed (None when it fails),
    whether a placement is reachable at all (IK from any seed),
    the joint state of a joint item (from the previous state), a pose in a frame (a link's taken at q) as a
    placement in the root frame, the smallest singular value of the tip's Jacobian at
    q, how to name a placement to the user, and a checkpoint that raises once the request is cancelled or out of
    time."""

    placement: Callable[[np.ndarray], pin.SE3]
    solve: Callable[[pin.SE3, np.ndarray], np.ndarray | None]
    reachable: Callable[[pin.SE3, np.ndarray], bool]
    joint_target: Callable[[Joint, np.ndarray], np.ndarray]
    in_root: Callable[[Pose, str, np.ndarray], pin.SE3]
    sigma: Callable[[np.ndarray], float]
    describe: Callable[[pin.SE3], str]
    checkpoint: Callable[[], None]


def build_path(start: np.ndarray, items: Sequence[Item], kinematics: Kinematics) -> list[Sample]:
    """The dense states from `start` through every item, corners with a blend radius rounded off."""
    samples = [Sample(start, kinematics.placement(start), -1, stop=True)]
    corners: list[int] = []
    for index, item in enumerate(items):
        if index == len(items) - 1 and item.blend > 0.0:
            raise _refused("the last item has a blend radius", what="blend 0 on the last item: the arm stops "
                           "at the end of a sequence", why=f"item {index} has blend {item.blend:g} m",
                           how="set blend=0 (the default) on the last item")
        kinematics.checkpoint()
        samples.extend(_segment(samples[-1], item, index, kinematics))
        if len(samples) > MAX_STEPS:
            raise _refused("the sequence has too many steps", code=MoveItCode.INVALID_GOAL_CONSTRAINTS,
                           what=f"at most {MAX_STEPS} states along the path (5 mm or 0.02 rad apart)",
                           why=f"items 0 to {index} already take {len(samples)}",
                           how="plan the sequence in parts, or with fewer or shorter moves")
        samples[-1].stop = True
        corners.append(len(samples) - 1)
    _check_radii(samples, items, corners)
    for index, corner in enumerate(corners[:-1]):
        if items[index].blend > 0.0:
            _check_turn(samples, corner, index, kinematics)
    for index in reversed(range(len(items) - 1)):
        if items[index].blend > 0.0:
            _blend(samples, corners[index], items, index, kinematics)
    return samples


def _segment(begin: Sample, item: Item, index: int, kinematics: Kinematics) -> list[Sample]:
    """The states of one item after `begin` (its last state is the item's end)."""
    if isinstance(item, Joint):
        goal = kinematics.joint_target(item, begin.q)
        count = max(int(np.ceil(np.abs(goal - begin.q).max() / JOINT_STEP)),
                    int(np.ceil(_travel(begin.tool, kinematics.placement(goal)) / MAX_STEP)), 1)
        states = [begin.q + (goal - begin.q) * k / count for k in range(1, count + 1)]
        return [Sample(q, kinematics.placement(q), index) for q in states]
    target = kinematics.in_root(item.pose, item.frame, begin.q)
    if not kinematics.reachable(target, begin.q):
        raise _refused(f"the pose of item {index} is outside the arm's workspace", code=MoveItCode.NO_IK_SOLUTION,
                       what="a pose the tool reaches with the joints within their limits",
                       why=f"no IK solution for item {index}'s pose {kinematics.describe(target)}",
                       how="give a pose within the arm's reach, in the right frame (frame= of the item)")
    if isinstance(item, Linear):
        placements = _line(begin.tool, target)
    else:
        point = kinematics.in_root(Pose(item.point), item.frame, begin.q).translation
        placements = _arc(begin.tool, target, point, item, index, kinematics.describe)
    return _follow(begin, placements, index, kinematics)


def _follow(begin: Sample, placements: Sequence[pin.SE3], index: int, kinematics: Kinematics,
            blend: bool = False) -> list[Sample]:
    """IK along `placements` from `begin`'s state, each checked for reach, flips and singularities."""
    where = f"the blend at the end of item {index}" if blend else f"item {index}"
    samples: list[Sample] = []
    q = begin.q
    for k, placement in enumerate(placements):
        solved = kinematics.solve(placement, q)
        share = f"{(k + 1) / len(placements):.0%} of the way along {where}"
        if solved is None:
            raise _refused(f"{where} leaves the arm's workspace", code=MoveItCode.NO_IK_SOLUTION,
                           what="a tool path whose every pose the arm reaches within its joint limits",
                           why=f"no IK solution at {share}, tool pose {kinematics.describe(placement)}",
                           how="move the points of the path closer to the arm (a pose within its reach, in the right "
                               "frame), or use a Joint item for that part")
        step = float(np.abs(solved - q).max())
        if step > FLIP_STEP:
            raise _refused(f"{where} needs a joint flip",
                           what=f"a tool path the joints follow without a jump (at most {FLIP_STEP:g} rad between "
                                f"states {MAX_STEP * 1e3:g} mm apart)",
                           why=f"the joints jump by {step:.2f} rad at {share}, tool pose "
                               f"{kinematics.describe(placement)}: the arm would change its configuration (elbow, "
                               "wrist or shoulder flip)",
                           how="pass that part with a Joint item, or choose points the arm reaches in one "
                               "configuration")
        sigma = kinematics.sigma(solved)
        if sigma < SINGULAR_SIGMA:
            raise _refused(f"{where} passes a singularity",
                           what=f"a tool path away from singular configurations (smallest singular value of the "
                                f"Jacobian at least {SINGULAR_SIGMA:g})",
                           why=f"it is {sigma:.3g} at {share}, tool pose {kinematics.describe(placement)}: the "
                               "tool's speed there would need joint speeds beyond any limit",
                           how="move the path away from the singular pose, or pass it with a Joint item")
        q = solved
        samples.append(Sample(q, placement, index, cartesian=True))
    return samples


def _line(begin: pin.SE3, end: pin.SE3) -> list[pin.SE3]:
    """Placements along the straight line, the orientation by slerp, at most MAX_STEP apart (the end included)."""
    count = max(int(np.ceil(_travel(begin, end) / MAX_STEP)), 1)
    return [along_line(begin, end, k / count) for k in range(1, count + 1)]


def _arc(begin: pin.SE3, end: pin.SE3, point: np.ndarray, item: Circular, index: int,
         describe: Callable[[pin.SE3], str]) -> list[pin.SE3]:
    """Placements along the arc from `begin` to `end` through the via point or around the centre (`point`, in the
    root frame), the orientation by slerp from start to end."""
    p0, p2 = begin.translation, end.translation
    if item.kind == "via":
        a, b = point - p0, p2 - p0
        normal = np.cross(a, b)
        if float(normal @ normal) < COLLINEAR:
            raise _collinear(index, "the start, via and end points lie on one line", describe(end))
        center = p0 + np.cross(a @ a * b - b @ b * a, normal) / (2.0 * float(normal @ normal))
    else:
        center = point
        r0, r2 = np.linalg.norm(p0 - center), np.linalg.norm(p2 - center)
        if abs(r0 - r2) > RADIUS_TOLERANCE:
            raise _refused(f"the centre of item {index} is not the centre of an arc to its end",
                           what=f"a centre equally far from the arc's start and end (within {RADIUS_TOLERANCE * 1e3:g} "
                                "mm)", why=f"the start is {r0 * 1e3:.1f} mm from it, the end "
                                           f"{describe(end)} {r2 * 1e3:.1f} mm",
                           how="give the arc's true centre, or a via point on the arc instead")
        normal = np.cross(p0 - center, p2 - center)
        if float(normal @ normal) < COLLINEAR:
            raise _collinear(index, "the start, centre and end lie on one line (the plane of a half circle is not "
                                    "defined by them)", describe(end))
    axis = normal / np.linalg.norm(normal)
    u = (p0 - center) / np.linalg.norm(p0 - center)
    w = np.cross(axis, u)
    radius0, radius2 = float(np.linalg.norm(p0 - center)), float(np.linalg.norm(p2 - center))
    angle = float(np.arctan2((p2 - center) @ w, (p2 - center) @ u)) % (2.0 * np.pi)
    length = max(radius0, radius2) * angle
    count = max(int(np.ceil(max(length, _rotation(begin, end)) / MAX_STEP)), 1)
    placements = []
    for k in range(1, count + 1):
        s = k / count
        radius = radius0 + (radius2 - radius0) * s
        position = center + radius * (np.cos(angle * s) * u + np.sin(angle * s) * w)
        placements.append(pin.SE3(along_line(begin, end, s).rotation, position))
    placements[-1] = end
    return placements


def _check_radii(samples: list[Sample], items: Sequence[Item], corners: list[int]) -> None:
    """Each move's tool travel holds the blend radii at both its ends (the blend spheres do not overlap)."""
    for index, item in enumerate(items):
        before = items[index - 1].blend if index > 0 else 0.0
        if before + item.blend <= 0.0:
            continue
        first = corners[index - 1] if index > 0 else 0
        points = np.array([sample.tool.translation for sample in samples[first:corners[index] + 1]])
        length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
        if before + item.blend > length * (1.0 + 1e-9):
            raise _refused(f"the blend radii around item {index} overlap",
                           what="blend radii at the two ends of a move that together fit its tool travel",
                           why=f"item {index} moves the tool {length * 1e3:.1f} mm; the blends at its start and end "
                               f"are {before * 1e3:.1f} mm and {item.blend * 1e3:.1f} mm",
                           how="give smaller blend radii, or points farther apart")


def _check_turn(samples: list[Sample], corner: int, index: int, kinematics: Kinematics) -> None:
    """Refuses a blend where the tool turns back on itself: it has to stop there."""
    here = samples[corner].tool.translation
    arriving, leaving = here - samples[corner - 1].tool.translation, samples[corner + 1].tool.translation - here
    cosine = float(arriving @ leaving) / max(float(np.linalg.norm(arriving) * np.linalg.norm(leaving)), 1e-12)
    if cosine < REVERSAL:
        raise _refused(f"the blend at the end of item {index} turns back on itself",
                       what="a blend at a corner the tool passes without stopping",
                       why=f"the tool turns by {np.degrees(np.arccos(max(cosine, -1.0))):.0f}° at item {index}'s end "
                           f"{kinematics.describe(samples[corner].tool)}: it must stop there",
                       how=f"set blend=0 on item {index}")


def _blend(samples: list[Sample], corner: int, items: Sequence[Item], index: int, kinematics: Kinematics) -> None:
    """Replace the states within the blend radius of the corner after item `index` by the blend curve, from where
    the tool crosses the sphere of that radius on the way in to where it crosses it on the way out."""
    radius = items[index].blend
    middle = samples[corner].tool.translation

    def outside(k: int) -> bool:
        return bool(np.linalg.norm(samples[k].tool.translation - middle) >= radius)

    entry = corner - 1
    while entry > 0 and not outside(entry) and not samples[entry].stop:
        entry -= 1
    leave = corner + 1
    while leave < len(samples) - 1 and not outside(leave) and not samples[leave].stop:
        leave += 1
    a = _on_sphere(samples[entry], samples[entry + 1], middle, radius, items[index], kinematics)
    b = _on_sphere(samples[leave], samples[leave - 1], middle, radius, items[index + 1], kinematics)
    c = samples[corner]
    tool_space = not isinstance(items[index], Joint) and not isinstance(items[index + 1], Joint)
    if tool_space:
        curve = _bezier(a.tool.translation, c.tool.translation, b.tool.translation)
        count = max(int(np.ceil(max(_polyline(curve(np.linspace(0.0, 1.0, 33))), _rotation(a.tool, b.tool))
                                / MAX_STEP)), 2)
        placements = [pin.SE3(along_line(a.tool, b.tool, s).rotation, curve(np.array([s]))[0])
                      for s in np.arange(1, count) / count]
        blended = _follow(a, [*placements, b.tool], index, kinematics, blend=True)[:-1]
    else:
        joints = _bezier(a.q, c.q, b.q)
        count = max(int(np.ceil(_polyline(joints(np.linspace(0.0, 1.0, 33))) / JOINT_STEP)),
                    int(np.ceil(2.0 * radius / MAX_STEP)), 2)
        cartesian = not (isinstance(items[index], Joint) and isinstance(items[index + 1], Joint))
        blended = [Sample(q, kinematics.placement(q), index, cartesian=cartesian)
                   for q in joints(np.arange(1, count) / count)]
    ends = (samples[entry], samples[leave])
    samples[entry + 1:leave] = [sample for sample in (a, *blended, b) if all(sample is not end for end in ends)]


def _on_sphere(outer: Sample, inner: Sample, middle: np.ndarray, radius: float, item: Item,
               kinematics: Kinematics) -> Sample:
    """The state between `outer` (at least `radius` from the corner `middle`) and `inner` (closer) where the tool is
    `radius` from it: on the straight tool step for a Cartesian move, on the joint step for a joint move. `outer`
    itself when it is that close already (a corner's stop)."""
    p, d = outer.tool.translation - middle, inner.tool.translation - outer.tool.translation
    if float(np.linalg.norm(p)) <= radius or not float(d @ d) > 0.0:
        return outer
    # |p + s d| = radius, the root in (0, 1]: the step enters the sphere
    half, constant = float(p @ d) / float(d @ d), (float(p @ p) - radius**2) / float(d @ d)
    share = float(np.clip(-half - np.sqrt(max(half**2 - constant, 0.0)), 0.0, 1.0))
    if isinstance(item, Joint):
        q = outer.q + share * (inner.q - outer.q)
        return Sample(q, kinematics.placement(q), outer.item, cartesian=outer.cartesian)
    placement = along_line(outer.tool, inner.tool, share)
    solved = kinematics.solve(placement, outer.q)
    return outer if solved is None else Sample(solved, placement, outer.item, cartesian=outer.cartesian)


def _bezier(a: np.ndarray, c: np.ndarray, b: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """The quintic Bézier curve from a to b around the corner c, at parameters s (a row per s): three control points
    on each leg (BEZIER_LEG of the way from the ends toward the corner), so it leaves and joins the legs tangent to
    them and with no curvature (no jump of the centripetal acceleration there), within the triangle a c b."""
    near, far = BEZIER_LEG
    controls = np.stack([a, a + near * (c - a), a + far * (c - a), b + far * (c - b), b + near * (c - b), b])
    binomial = np.array([1.0, 5.0, 10.0, 10.0, 5.0, 1.0])
    powers = np.arange(6)

    def at(s: np.ndarray) -> np.ndarray:
        s = s[:, None]
        weights = binomial * s**powers * (1.0 - s) ** (5 - powers)
        result: np.ndarray = weights @ controls
        return result
    return at


def _polyline(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def _rotation(a: pin.SE3, b: pin.SE3) -> float:
    """The angle (rad) the tool turns from `a` to `b`."""
    return float(np.linalg.norm(pin.log3(a.rotation.T @ b.rotation)))


def _travel(a: pin.SE3, b: pin.SE3) -> float:
    """Tool travel between two placements: distance plus rotation at 1 rad per metre."""
    return float(np.linalg.norm(b.translation - a.translation)) + _rotation(a, b)


def _collinear(index: int, why: str, end: str) -> PlanningError:
    return _refused(f"item {index} spans no arc", what="three points that span a circle",
                    why=f"{why}; end {end}", how="give a via point (or centre) off the line from start to end")


def _refused(summary: str, *, what: str, why: str, how: str,
             code: MoveItCode = MoveItCode.INVALID_MOTION_PLAN) -> PlanningError:
    """A refusal of a sequence (items are counted from 0)."""
    return PlanningError(summary, what=what, why=why, how=how, code=code)
