"""The planner: inverse and forward kinematics, the planning scene, collision-free plans and Cartesian paths.

Positions are in the arm's joint order everywhere in this API. A plan starts at rest at the start state, is
checked densely against the robot and the scene and against every limit, and comes back as a trajectory
that plem's trajectory path runs as sent. One planner is not thread-safe: callers serialise requests.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from plem.control.kinematics import ArmDynamics, has_link, link_frame
from plem.control.limits import ArmLimits
from plem.control.spline import Spline
from plem.control.trajectory import JointTrajectory
from plem.core.paths import pinned_packages
from plem.description.model import SrdfModel, UrdfModel
from plem.description.validate import ValidationReport
from plem.errors import CommandRejected, MoveItCode, PlanningError
from plem.ipc.request_bounds import MIN_SPEED_SCALE
from plem.planning.cartesian import cartesian_states
from plem.planning.collision import CollisionChecker
from plem.planning.goals import (
    MAX_IK_TIMEOUT_S,
    MAX_PLANNING_TIME_S,
    Goal,
    NamedGoal,
    Plan,
    PlanOptions,
    PoseGoal,
    goal_of,
)
from plem.planning.groups import PlanningGroup, read_groups
from plem.planning.inverse_kinematics import IkResult, IkSolver
from plem.planning.named_states import resolve_state, with_zero
from plem.planning.parameterisation import parameterise, planning_limits, to_trajectory
from plem.planning.path_timing import time_path
from plem.planning.paths import plan_path
from plem.planning.poses import Pose
from plem.planning.retiming import as_sent
from plem.planning.scene import PlanningScene
from plem.planning.sequence import Circular, Item, Joint, Linear, ToolLimits
from plem.planning.tool_paths import Kinematics, Sample, build_path

#: Pilz's planner id of each kind of item (a sequence of one item is named by it).
ITEM_IDS = {Joint: "PTP", Linear: "LIN", Circular: "CIRC"}
#: Planning attempts when the dense re-check finds a contact the planner's coarser checks missed.
ATTEMPTS = 3
#: Distinct collision-free IK solutions gathered as the goal set of a pose goal.
GOAL_SOLUTIONS = 4
#: Position (m) and orientation (rad) error within which an IK answer reaches its pose (KDL's eps).
POSE_TOLERANCE = 1e-5
#: A start state this far outside a position limit (rad) is taken as on the limit (encoder noise).
START_SLACK = 1e-6
#: Commanded states re-checked between two looks at whether the request was cancelled.
CANCEL_CHECK_STATES = 1000
#: Most a joint moves (rad or m) between two states the dense re-check checks: every cycle's state at full speed,
#: fewer of a slow plan's (at a speed scale of 0.001 one in several hundred), whose cycles barely move.
RECHECK_STEP = 1e-3


class Planner:
    """Everything planning needs about one arm, and the scene around it."""

    def __init__(self, urdf_xml: str, urdf: UrdfModel, srdf: SrdfModel, joint_names: Sequence[str],
                 limits: ArmLimits, cycle_time_s: float, kinematics: Path | None = None,
                 frame_prefix: str = "", packages: Mapping[str, Path] | None = None) -> None:
        #: Packages `package://` URIs resolve to before the search path (the launched package, given by path).
        self.packages = dict(packages or {})
        #: Asked while a request runs: true when its client cancelled it or went away (set by the planner's service).
        self.cancelled: Callable[[], bool] = _never
        self.arm = ArmDynamics(urdf_xml, joint_names)
        self.joint_names = tuple(joint_names)
        self.limits = limits
        self.cycle_time_s = cycle_time_s
        self.frame_prefix = frame_prefix
        self.root_link = urdf.roots()[0] if urdf.roots() else ""
        self.groups, self.warnings = read_groups(srdf, urdf, self.joint_names, kinematics)
        if not self.groups:
            raise PlanningError("the SRDF has no planning group for the arm's joints",
                                what="an SRDF <group> (a chain or joints) over the arm's joints",
                                why=f"groups: {', '.join(srdf.groups) or 'none'}",
                                how="add <group name=\"arm\"><chain base_link=... tip_link=.../></group> to the SRDF",
                                code=MoveItCode.INVALID_GROUP_NAME)
        #: The SRDF's group_states and `zero` (see plem.planning.named_states), in the arm's joint order.
        self.named_states = {name: np.array(values) for name, values in
                             with_zero(srdf.poses(self.joint_names), len(self.joint_names)).items()}
        self.scene = PlanningScene()
        self.urdf_xml = urdf_xml
        self.disabled_pairs = [(a, b) for a, b, _ in srdf.disabled_collisions]
        with pinned_packages(self.packages):
            self.collisions = CollisionChecker(self.arm.model, urdf_xml, self.disabled_pairs)
        self._scene_version = self.scene.version
        self._lower = self.arm.to_model_order(limits.min_position)
        self._upper = self.arm.to_model_order(limits.max_position)
        self._solvers: dict[tuple[str, str], IkSolver] = {}
        #: The start of the request being planned when it is outside a position limit (see `_start`), else None.
        self._entry: np.ndarray | None = None
        self._rng = np.random.default_rng()
        #: How many plans were made, and the newest (what the view shows before it executes).
        self.plans_made = 0
        self.latest_plan: Plan | None = None

    @classmethod
    def for_package(cls, report: ValidationReport, joint_names: Sequence[str], limits: ArmLimits,
                    cycle_time_s: float, frame_prefix: str = "") -> Planner:
        """The planner of a validated description package (start-up stage or later, with an SRDF)."""
        if report.srdf is None or report.urdf is None or report.urdf_xml is None:
            raise PlanningError("planning needs an SRDF", what="srdf/NAME.srdf in the description package",
                                why=f"package {report.files.name} has none",
                                how="add an SRDF with a planning group (see docs/planning.md), or launch with "
                                    "planner:=false", code=MoveItCode.INVALID_GROUP_NAME)
        return cls(report.urdf_xml, report.urdf, report.srdf, joint_names, limits, cycle_time_s,
                   report.files.kinematics, frame_prefix, {report.files.name: report.files.root})

    # -- names --------------------------------------------------------------------------------------------
    def group(self, name: str = "") -> PlanningGroup:
        """The group called `name`; '' for the first of the SRDF."""
        if not name:
            return next(iter(self.groups.values()))
        if name not in self.groups:
            raise PlanningError(f"unknown planning group {name!r}", what=f"one of {', '.join(self.groups)}",
                                why=f"the SRDF defines no group {name!r} over the arm's joints",
                                how="name a group of the SRDF, or leave the group empty for the first",
                                code=MoveItCode.INVALID_GROUP_NAME)
        return self.groups[name]

    def link_name(self, name: str) -> str:
        """A link of the URDF, given with or without the robot's frame prefix ('' and 'world': the root link)."""
        plain = name.removeprefix(self.frame_prefix) if self.frame_prefix else name
        if plain in ("", "world", self.root_link):
            return self.root_link
        if not has_link(self.arm.model, plain):
            links = [f.name for f in self.arm.model.frames if f.type == pin.FrameType.BODY]
            raise PlanningError(f"unknown link {name!r}", what=f"a link of the URDF ({', '.join(links)})",
                                why=f"the URDF has no link {plain!r}",
                                how="use a link name from the robot's URDF, or 'world'",
                                code=MoveItCode.INVALID_LINK_NAME)
        return plain

    # -- kinematics ---------------------------------------------------------------------------------------
    def fk(self, positions: Sequence[float], links: Sequence[str], frame: str = "") -> dict[str, Pose]:
        """The pose of each link in `frame` (a link; '' for the root) at `positions`."""
        q = self._configuration(positions, "the positions")
        base = self._placement(q, self.link_name(frame)).inverse()
        return {link: pose_of(base * self._placement(q, self.link_name(link))) for link in links}

    def ik(self, pose: Pose, seed: Sequence[float], *, frame: str = "", group: str = "", link: str = "",
           timeout_s: float | None = None, avoid_collisions: bool = True, position_only: bool = False) -> np.ndarray:
        """Joint positions that put `link` (the group's tip) at `pose` in `frame`, nearest the seed found;
        collision-free with `avoid_collisions`. Raises PlanningError NO_IK_SOLUTION with the tries and the best
        residual."""
        if timeout_s is not None and timeout_s > MAX_IK_TIMEOUT_S:
            raise PlanningError("the IK timeout is too long", what=f"an IK timeout of at most {MAX_IK_TIMEOUT_S:g} s",
                                why=f"the request asks for {timeout_s:g} s (the planner serves one request at a time)",
                                how=f"ask for {MAX_IK_TIMEOUT_S:g} s or less (timeout in the IK request), or 0 for "
                                    "kinematics.yaml's kinematics_solver_timeout", code=MoveItCode.TIMED_OUT)
        chosen = self.group(group)
        start = self._configuration(seed, "the seed")
        self._sync_scene()
        target = self._in_root(pose, frame, start)
        solver = self._solver(chosen, link)
        budget = chosen.settings.budget_s if timeout_s is None or timeout_s <= 0 else timeout_s
        result = solver.solve(target, start, timeout_s=budget, position_only=position_only,
                              accept=self.collisions.is_free if avoid_collisions else None, rng=self._rng,
                              stop=self.cancelled)
        self._check_cancelled()
        if not result.success:
            raise self._no_solution(chosen, link or chosen.tip_link, result, result.attempts, budget)
        return self.arm.to_arm_order(result.positions)

    # -- planning -----------------------------------------------------------------------------------------
    def plan(self, start: Sequence[float], goal: Goal, options: PlanOptions | None = None) -> Plan:
        """A collision-free motion from rest at `start` to `goal`, timed within the limits and checked densely."""
        began = time.perf_counter()
        options, group, q_start = self._prepare(start, options)
        goals = self._goal_states(goal, q_start, group, options, began)
        indices = self._indices(group)
        fixed = q_start.copy()

        def free(values: np.ndarray) -> bool:
            fixed[indices] = values
            return self.collisions.is_free(fixed)

        is_free = free if options.avoid_collisions else _always_free
        last: PlanningError | None = None
        for _ in range(ATTEMPTS):
            remaining = options.timeout_s - (time.perf_counter() - began)
            if remaining <= 0.0:
                break
            try:
                path = plan_path(self._lower[indices], self._upper[indices], is_free, q_start[indices],
                                 [q[indices] for q in goals], options.planner_id, remaining, self.cancelled)
            except PlanningError:
                self._check_cancelled()
                raise
            states = np.repeat(q_start[None], len(path.states), axis=0)
            states[:, indices] = path.states
            try:
                return self._timed(states, options, began, path.planner, straight=True)
            except PlanningError as problem:
                last = problem
        raise last or PlanningError("no time was left to plan", what=f"a plan within {options.timeout_s:g} s",
                                    why="finding the goal states took the whole planning time",
                                    how="allow more planning time (allowed_planning_time, --planning-time)",
                                    code=MoveItCode.TIMED_OUT)

    def cartesian(self, start: Sequence[float], waypoints: Sequence[Pose], *, frame: str = "", link: str = "",
                  max_step: float = 0.01, jump_threshold: float = 0.0, options: PlanOptions | None = None) -> Plan:
        """A motion moving `link` (the group's tip) along straight lines through `waypoints` (in `frame`), as far
        as it can go; `fraction` tells how much of the way (MoveIt's compute_cartesian_path)."""
        began = time.perf_counter()
        options, group, q_start = self._prepare(start, options)
        tip = self._frame_id(self.link_name(link or group.tip_link))
        targets = [self._in_root(pose, frame, q_start) for pose in waypoints]
        step = self._stepper(group, link, options, began, "use a larger max_step (fewer steps)")
        states, fraction = cartesian_states(q_start, targets, lambda q: self._placement_at(q, tip),
                                            step, max_step, jump_threshold,
                                            self.collisions.is_free if options.avoid_collisions else _always_free)
        if len(states) < 2:
            raise PlanningError("the Cartesian path cannot start", what="a first step along the line",
                                why="inverse kinematics, a joint limit or a collision stops it at the start",
                                how="check the waypoints are reachable from the current state",
                                code=MoveItCode.NO_IK_SOLUTION)
        plan = self._timed(states, options, began, "cartesian", straight=False)
        return Plan(plan.trajectory, plan.duration_s, plan.planning_time_s, plan.planner, plan.path_states,
                    plan.path_length, plan.checked_states, fraction)

    def sequence(self, start: Sequence[float], items: Sequence[Item], *, link: str = "",
                 tool_limits: ToolLimits | None = None, options: PlanOptions | None = None) -> Plan:
        """A motion through joint (PTP), straight (LIN) and circular (CIRC) items, passing the corners that have a
        blend radius without stopping, timed within the joint limits and, on its Cartesian parts, the tool limits
        (see plem.planning.tool_paths and plem.planning.path_timing); refused, naming the item and pose, where it
        cannot be followed."""
        began = time.perf_counter()
        options, group, q_start = self._prepare(start, options)
        tip = self._frame_id(self.link_name(link or group.tip_link))
        indices = self._indices(group)
        data = self.arm.model.createData()

        def sigma(q: np.ndarray) -> float:
            jacobian = pin.computeFrameJacobian(self.arm.model, data, q, tip, pin.LOCAL_WORLD_ALIGNED)[:, indices]
            return float(np.linalg.svd(jacobian, compute_uv=False)[-1])

        def joint_target(item: Joint, q: np.ndarray) -> np.ndarray:
            goal = goal_of(item.target, self.joint_names, item.frame)
            if isinstance(goal, PoseGoal) and goal.link == "" and link:
                goal = PoseGoal(goal.pose, goal.frame, link)
            return self._goal_states(goal, q, group, options, began)[0]

        solver = self._solver(group, link)

        def reachable(target: pin.SE3, seed: np.ndarray) -> bool:
            return solver.solve(target, seed, timeout_s=group.settings.budget_s, rng=self._rng,
                                stop=self.cancelled).success

        kinematics = Kinematics(
            placement=lambda q: self._placement_at(q, tip),
            solve=self._stepper(group, link, options, began, "use fewer or shorter moves"), reachable=reachable,
            joint_target=joint_target, in_root=lambda pose, frame, q: self._in_root(pose, frame, q),
            sigma=sigma, describe=lambda placement: f"{describe(placement)} in {self.root_link}",
            checkpoint=lambda: self._within(options, began, "use fewer or shorter moves"))
        samples = build_path(q_start, items, kinematics)
        if self._entry is not None:  # from outside a position range: back into it first (see `_start`)
            samples.insert(0, Sample(self._entry, kinematics.placement(self._entry), -1, stop=True))
        if options.avoid_collisions:
            for index, sample in enumerate(samples):
                if index % CANCEL_CHECK_STATES == 0:
                    kinematics.checkpoint()
                if not self.collisions.is_free(sample.q):
                    self._require_free(sample.q, f"the path at item {sample.item} (tool pose "
                                                 f"{kinematics.describe(sample.tool)})", MoveItCode.INVALID_MOTION_PLAN)
        arm_states = np.array([self.arm.to_arm_order(sample.q) for sample in samples])
        limits = planning_limits(self.limits.reaching(arm_states[0]), options.velocity_scale,
                                 options.acceleration_scale)
        tool = (tool_limits or ToolLimits()).scaled(options.velocity_scale, options.acceleration_scale)
        motion = time_path(arm_states, np.array([sample.tool.translation for sample in samples]),
                           np.array([sample.tool.rotation for sample in samples]),
                           np.array([sample.stop for sample in samples]),
                           np.array([sample.cartesian for sample in samples]), limits, tool, self.cycle_time_s)
        kinds = {type(item) for item in items}
        name = ITEM_IDS[kinds.pop()] if len(items) == 1 else "sequence"
        return self._checked(to_trajectory(motion), arm_states, options, began, name)

    # -- the scene ----------------------------------------------------------------------------------------
    def contacts(self, positions: Sequence[float]) -> list[tuple[str, str]]:
        """Every colliding pair (link or object names) at `positions`."""
        self._sync_scene()
        return self.collisions.contacts(self._configuration(positions, "the positions"))

    def link_pose(self, positions: Sequence[float], link: str) -> pin.SE3:
        """The placement of `link` in the root frame at `positions` (to attach an object where it is)."""
        return self._placement(self._configuration(positions, "the positions"), self.link_name(link))

    def attach(self, name: str, link: str, touch_links: Sequence[str], positions: Sequence[float]) -> None:
        """Attach world object `name` to `link` where it is at `positions`: it then moves with the link."""
        item = self.scene.get(name)
        holder = self.link_name(link)
        where = self.link_pose(positions, item.frame) * placement_of(item.pose)
        self.scene.attach(name, holder, pose_of(self.link_pose(positions, holder).actInv(where)),
                          tuple(self.link_name(touch) for touch in touch_links))

    def detach(self, name: str, positions: Sequence[float]) -> None:
        """Leave attached object `name` in the world where it is at `positions` (a world object stays as it is)."""
        item = self.scene.get(name)
        if item.attached_to is not None:
            where = self.link_pose(positions, item.attached_to) * placement_of(item.pose)
            self.scene.detach(name, pose_of(where))

    # -- internals ----------------------------------------------------------------------------------------
    def _configuration(self, positions: Sequence[float], what: str) -> np.ndarray:
        try:
            values = self.limits.check_vector(positions, what)
        except CommandRejected as error:
            raise PlanningError(error.summary, what=error.what, why=error.why, how=error.how,
                                code=MoveItCode.INVALID_ROBOT_STATE) from None
        return self.arm.to_model_order(values)

    def _prepare(self, start: Sequence[float], options: PlanOptions | None
                 ) -> tuple[PlanOptions, PlanningGroup, np.ndarray]:
        """The options (defaults when None), the group they name and the start configuration, checked to be within
        the limits and, when collisions are avoided, free of them."""
        options = options or PlanOptions()
        _check_options(options)
        group = self.group(options.group)
        unlimited = [name for name in group.joints
                     if not np.isfinite(self.limits.max_velocity[self.joint_names.index(name)])]
        if unlimited:
            raise PlanningError(f"group {group.name} has joints without a velocity limit",
                                what="a velocity limit for every joint of the group, to time plans within",
                                why=f"no max_velocity for {', '.join(unlimited)} (neither the URDF's <limit velocity> "
                                    "nor joint_limits.yaml gives one)",
                                how="add has_velocity_limits: true and max_velocity to those joints in "
                                    "config/joint_limits.yaml", code=MoveItCode.PLANNING_FAILED)
        q_start = self._start(start)
        self._sync_scene()
        if options.avoid_collisions:
            self._require_free(q_start, "the start state", MoveItCode.START_STATE_IN_COLLISION)
        return options, group, q_start

    def _start(self, start: Sequence[float]) -> np.ndarray:
        """The state planning starts from: `start`, brought into the position limits. An arm outside a range is
        planned for from the nearest state inside it, and the plan begins with the straight move there (back toward
        the range, never farther out: `_timed`), so a plan can bring it back."""
        q = self._configuration(start, "the start state")
        outside = (q < self._lower - START_SLACK) | (q > self._upper + START_SLACK)
        self._entry = q if outside.any() else None
        clipped: np.ndarray = np.clip(q, self._lower, self._upper)
        return clipped

    def _indices(self, group: PlanningGroup) -> np.ndarray:
        order = self.arm.model_indices
        return np.array(sorted(int(order[self.joint_names.index(name)]) for name in group.joints), dtype=np.intp)

    def _frame_id(self, link: str) -> int:
        return link_frame(self.arm.model, link)

    def _placement(self, q: np.ndarray, link: str) -> pin.SE3:
        return self._placement_at(q, self._frame_id(link))

    def _placement_at(self, q: np.ndarray, frame: int) -> pin.SE3:
        """Placement of frame number `frame` at configuration `q` (pinocchio's order)."""
        return self.arm.frame_placement(self.arm.to_arm_order(q), frame)

    def _in_root(self, pose: Pose, frame: str, q: np.ndarray) -> pin.SE3:
        """`pose` in `frame` as a placement in the root frame (a link's frame is taken at configuration `q`)."""
        link = self.link_name(frame)
        target = placement_of(pose)
        return target if link == self.root_link else self._placement(q, link) * target

    def _solver(self, group: PlanningGroup, link: str) -> IkSolver:
        tip = self.link_name(link or group.tip_link)
        key = (group.name, tip)
        if key not in self._solvers:
            self._solvers[key] = IkSolver(self.arm.model, self._indices(group).tolist(), tip, self._lower,
                                          self._upper)
        return self._solvers[key]

    def _stepper(self, group: PlanningGroup, link: str, options: PlanOptions, began: float, fewer: str
                 ) -> Callable[[pin.SE3, np.ndarray], np.ndarray | None]:
        """IK for the steps of a Cartesian path, from the previous state (None where it fails), within the request's
        planning time (else TIMED_OUT, whose HOW starts with `fewer`: how to ask for fewer steps) and cancellable."""
        solver = self._solver(group, link)

        def step(target: pin.SE3, seed: np.ndarray) -> np.ndarray | None:
            self._within(options, began, fewer)
            left = began + options.timeout_s - time.perf_counter()
            result = solver.solve(target, seed, timeout_s=max(min(group.settings.timeout_s, left), 1e-4),
                                  stop=self.cancelled)
            return result.positions if result.success else None

        return step

    def _within(self, options: PlanOptions, began: float, fewer: str) -> None:
        """Raises PREEMPTED once the request is cancelled, TIMED_OUT once its planning time is spent (the HOW starts
        with `fewer`: how to ask for less)."""
        self._check_cancelled()
        if time.perf_counter() - began >= options.timeout_s:
            raise PlanningError("the path took longer than its planning time",
                                what=f"a Cartesian path or sequence within {options.timeout_s:g} s",
                                why=f"solving its steps took longer than {options.timeout_s:g} s",
                                how=f"{fewer} or allow more planning time "
                                    f"(--planning-time, at most {MAX_PLANNING_TIME_S:g} s)",
                                code=MoveItCode.TIMED_OUT)

    def _sync_scene(self) -> None:
        if self.scene.version != self._scene_version:
            with pinned_packages(self.packages):
                self.collisions.set_scene(self.scene)
            self._scene_version = self.scene.version

    def _check_cancelled(self) -> None:
        """Raises PREEMPTED when the request running was cancelled or its client went away."""
        if self.cancelled():
            raise PlanningError("the request was cancelled", what="a request its client still waits for",
                                why="its client cancelled it or closed its connection",
                                how="send the request again when it is wanted", code=MoveItCode.PREEMPTED)

    def _require_free(self, q: np.ndarray, what: str, code: MoveItCode) -> None:
        contacts = self.collisions.contacts(q)
        if contacts:
            pairs = ", ".join(f"{a} with {b}" for a, b in contacts[:8]) + (" ..." if len(contacts) > 8 else "")
            raise PlanningError(f"{what} is in collision", what=f"{what} free of collisions",
                                why=f"in contact: {pairs}",
                                how="move the objects named (apply_planning_scene, plem scene) or choose another "
                                    "state; a contact the arm can never leave belongs in the SRDF's "
                                    "<disable_collisions>", code=code)

    def _goal_states(self, goal: Goal, q_start: np.ndarray, group: PlanningGroup, options: PlanOptions,
                     began: float) -> list[np.ndarray]:
        if isinstance(goal, PoseGoal):
            return self._pose_goals(goal, q_start, group, options, began)
        if isinstance(goal, NamedGoal):
            state = self.named_states[resolve_state(goal.name, self.named_states)]
            positions = dict(zip(self.joint_names, state, strict=True))
        else:
            positions = goal.positions
        unknown = sorted(set(positions) - set(self.joint_names))
        if unknown:
            raise PlanningError("the goal names unknown joints",
                                what=f"joints of the arm ({', '.join(self.joint_names)})",
                                why=f"unknown: {', '.join(unknown)}", how="name the arm's joints",
                                code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
        target = self.arm.to_arm_order(q_start)
        for name, value in positions.items():
            target[self.joint_names.index(name)] = value
        try:
            values = self.limits.check_vector(target, "the goal")
            self.limits.check_positions(values, "the goal")
        except CommandRejected as error:
            raise PlanningError(error.summary, what=error.what, why=error.why, how=error.how,
                                code=MoveItCode.INVALID_GOAL_CONSTRAINTS) from None
        q_goal = self.arm.to_model_order(values)
        start = self.arm.to_arm_order(q_start)
        names = [name for name, before, after in zip(self.joint_names, start, values, strict=True)
                 if before != after and name not in group.joints]
        if names:
            raise PlanningError(f"the goal moves joints outside group {group.name!r}",
                                what=f"a goal for the joints of {group.name} ({', '.join(group.joints)})",
                                why=f"it also moves {', '.join(names)}", how="plan for a group holding those joints",
                                code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
        if options.avoid_collisions:
            self._require_free(q_goal, "the goal", MoveItCode.GOAL_IN_COLLISION)
        return [q_goal]

    def _pose_goals(self, goal: PoseGoal, q_start: np.ndarray, group: PlanningGroup, options: PlanOptions,
                    began: float) -> list[np.ndarray]:
        """Distinct IK solutions for the goal pose, nearest the start first: the planner's goal set."""
        solver = self._solver(group, goal.link)
        target = self._in_root(goal.pose, goal.frame, q_start)
        indices = self._indices(group)
        accept = self.collisions.is_free if options.avoid_collisions else None
        budget = group.settings.budget_s
        solutions: list[np.ndarray] = []
        attempts = 0
        seed = q_start
        deadline = began + min(options.timeout_s / 2, budget * GOAL_SOLUTIONS)
        while True:  # one search at least, however little time is left
            result = solver.solve(target, seed, timeout_s=min(budget, max(deadline - time.perf_counter(), 1e-4)),
                                  position_only=goal.position_only, accept=accept, rng=self._rng,
                                  stop=self.cancelled)
            self._check_cancelled()
            attempts += result.attempts
            if result.success:
                if not any(np.abs(result.positions - q).max() < 1e-3 for q in solutions):
                    solutions.append(result.positions)
            elif not solutions:
                raise self._no_solution(group, goal.link or group.tip_link, result, attempts, budget)
            if len(solutions) >= GOAL_SOLUTIONS or time.perf_counter() >= deadline:
                break
            seed = q_start.copy()
            seed[indices] = self._rng.uniform(np.maximum(self._lower[indices], -2 * np.pi),
                                              np.minimum(self._upper[indices], 2 * np.pi))
        return sorted(solutions, key=lambda q: float(np.abs(q - q_start).max()))  # the nearest first

    def _no_solution(self, group: PlanningGroup, link: str, best: IkResult, attempts: int, budget: float
                     ) -> PlanningError:
        """Why IK failed: the pose is out of reach (with the closest it came), or every solution collides."""
        reached = best.position_error <= POSE_TOLERANCE and best.orientation_error <= POSE_TOLERANCE
        if reached:
            contacts = ", ".join(f"{a} with {b}" for a, b in self.collisions.contacts(best.positions)[:4])
            why = (f"{attempts} seeds tried in {budget * 1e3:.3g} ms; every solution found is in collision "
                   f"(e.g. {contacts or 'a collision'})")
            how = ("move the objects named (plem scene, apply_planning_scene), choose another pose, or allow more "
                   "time (kinematics_solver_timeout in kinematics.yaml, timeout in the request)")
        else:
            why = (f"{attempts} seeds tried in {budget * 1e3:.3g} ms; the closest came within "
                   f"{best.position_error * 1e3:.3g} mm and {np.degrees(best.orientation_error):.3g}° of the pose")
            how = ("check the pose is within the arm's reach and in the right frame (--frame, header.frame_id); allow "
                   "more time (kinematics_solver_timeout in kinematics.yaml, timeout in the request)")
        return PlanningError(f"no{' collision-free' if reached else ''} IK solution for {link}",
                             what=f"joint positions of group {group.name} within their limits that reach the pose",
                             why=why, how=how, code=MoveItCode.NO_IK_SOLUTION)

    def _timed(self, states: np.ndarray, options: PlanOptions, began: float, planner: str, straight: bool) -> Plan:
        """The path (rows in pinocchio's order) timed within the limits and re-checked densely; from the start outside
        a range when there is one (`_start`)."""
        if self._entry is not None:
            states = np.vstack([self._entry, states])
        arm_states = np.array([self.arm.to_arm_order(q) for q in states])
        limits = planning_limits(self.limits.reaching(arm_states[0]), options.velocity_scale,
                                 options.acceleration_scale)
        trajectory = to_trajectory(parameterise(arm_states, limits, self.cycle_time_s, straight=straight))
        return self._checked(trajectory, arm_states, options, began, planner)

    def _checked(self, trajectory: JointTrajectory, arm_states: np.ndarray, options: PlanOptions, began: float,
                 planner: str) -> Plan:
        """The plan of a timed path through `arm_states` (the arm's order), once re-checked densely (`_recheck`)."""
        motion, checked = self._recheck(trajectory, arm_states[0], options)
        length = float(np.linalg.norm(np.diff(arm_states, axis=0), axis=1).sum())
        plan = Plan(trajectory, motion.duration, time.perf_counter() - began, planner, len(arm_states), length,
                    checked)
        self.plans_made += 1
        self.latest_plan = plan
        return plan

    def _recheck(self, trajectory: JointTrajectory, start: np.ndarray, options: PlanOptions) -> tuple[Spline, int]:
        """The motion the RT driver makes of the trajectory, read back as its command path reads it: checked to keep
        every limit the core enforces as sent (so it runs unchanged, never re-timed), and the states it commands
        (one per control cycle, or as many cycles apart as keep every joint within RECHECK_STEP of a checked
        state) checked against the robot and the scene. Returns it and the states checked."""
        rest = np.zeros(len(start))
        try:
            motion = as_sent(trajectory, self.limits.reaching(start), (start, rest, rest), self.cycle_time_s)
        except CommandRejected as error:
            raise PlanningError("the timed plan breaks a limit", what="a plan within every limit the driver enforces",
                                why=error.why, how="report this: plans are timed within the limits",
                                code=MoveItCode.INVALID_MOTION_PLAN) from None
        speeds = self.limits.max_velocity[np.isfinite(self.limits.max_velocity)] * options.velocity_scale
        fastest = float(speeds.max()) if speeds.size else 0.0  # no joint moves faster (plans use 99 % of it)
        cycles = max(int(RECHECK_STEP / (fastest * self.cycle_time_s)), 1) if fastest > 0 else 1
        times = np.append(np.arange(0.0, motion.duration, self.cycle_time_s * cycles), motion.duration)
        for index, t in enumerate(times):
            if index % CANCEL_CHECK_STATES == 0:
                self._check_cancelled()
            q = self.arm.to_model_order(motion.state_at(float(t))[0])
            if options.avoid_collisions and not self.collisions.is_free(q):
                contacts = self.collisions.contacts(q)
                raise PlanningError("the timed plan touches an obstacle", what="a collision-free motion",
                                    why=f"at {t:.3f} s: " + ", ".join(f"{a} with {b}" for a, b in contacts),
                                    how="plan again; the planner retries this itself within its time",
                                    code=MoveItCode.INVALID_MOTION_PLAN)
        return motion, len(times)


def _check_options(options: PlanOptions) -> None:
    """Raises unless the planning time is at most the maximum and the speed scales at least the minimum."""
    if not 0.0 < options.timeout_s <= MAX_PLANNING_TIME_S:
        raise PlanningError("the planning time is out of range",
                            what=f"a planning time in (0, {MAX_PLANNING_TIME_S:g}] s",
                            why=f"the request asks for {options.timeout_s:g} s (the planner serves one request at "
                                "a time)",
                            how=f"ask for {MAX_PLANNING_TIME_S:g} s or less (--planning-time, allowed_planning_time "
                                "in ROS, PlanOptions.timeout_s)", code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
    for name, scale in (("velocity", options.velocity_scale), ("acceleration", options.acceleration_scale)):
        if not MIN_SPEED_SCALE <= scale <= 1.0:
            raise PlanningError(f"the {name} scale is out of range",
                                what=f"a {name} scale from {MIN_SPEED_SCALE:g} to 1 (a share of the limits)",
                                why=f"the request asks for {scale:g}"
                                    + (f": a plan then takes over {1 / MIN_SPEED_SCALE:g} times as long as at full "
                                       "speed" if scale < MIN_SPEED_SCALE else ""),
                                how=f"scale by {MIN_SPEED_SCALE:g} or more (--speed-scale, max_{name}_scaling_factor "
                                    f"in ROS, PlanOptions.{name}_scale)", code=MoveItCode.INVALID_GOAL_CONSTRAINTS)


def _never() -> bool:
    """The cancel check outside requests: nothing to cancel."""
    return False


def _always_free(values: np.ndarray) -> bool:
    """The validity check with collision checking off."""
    return True


def placement_of(pose: Pose) -> pin.SE3:
    """A pose as a pinocchio placement."""
    x, y, z, w = pose.orientation
    return pin.SE3(pin.Quaternion(w, x, y, z).toRotationMatrix(), np.array(pose.position))


def describe(placement: pin.SE3) -> str:
    """A placement for a message: position (m) and quaternion x y z w."""
    pose = pose_of(placement)
    return (f"position ({', '.join(f'{v:.3f}' for v in pose.position)}) m, orientation "
            f"({', '.join(f'{v:.3f}' for v in pose.orientation)})")


def pose_of(placement: pin.SE3) -> Pose:
    """A pinocchio placement as a pose."""
    x, y, z, w = (float(v) for v in pin.Quaternion(placement.rotation).coeffs())
    p = placement.translation
    return Pose((float(p[0]), float(p[1]), float(p[2])), (x, y, z, w))
