"""Collision checking of the arm against itself and the planning scene, through pinocchio and coal.

The robot's shapes are the URDF's `<collision>` elements (primitives and meshes, `package://` resolved on
plem's package search path). Pairs of links are never checked when the SRDF disables them, when they lie on
one rigid body (they cannot move relative to each other), or when their bodies are joined directly by a joint
(adjacent, counting links on fixed joints as part of their body, as MoveIt's setup assistant does). World
objects are checked against every link, attached objects against every link but the one holding them and
their touch links, against world objects, and against objects held by other bodies.

`is_free` is the planner's hot path: an AABB tree over every shape (coal's broad phase) leaves the exact
test to the pairs whose boxes overlap, and it stops at the first collision. `contacts` tests every pair and
names each colliding one. The exact test starts from the same guess every time (not the last call's), so an
answer depends on the configuration alone. (coal's array-based AABB tree misses overlaps here; the linked
tree does not.)
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
from lxml import etree

from plem.control.kinematics import JointSpace, link_frame
from plem.core.paths import resolve_package_uri
from plem.description.model import parse_xml
from plem.description.problems import DescriptionError
from plem.errors import PlemError
from plem.planning.scene import (
    WORLD,
    Box,
    Cylinder,
    PlanningScene,
    SceneError,
    SceneErrors,
    SceneObject,
    Shape,
    Sphere,
    TriangleMesh,
)

#: The name parse errors give the URDF text (it reaches the checker as text, not as a file).
URDF_SOURCE = Path("robot_description")
VALIDATE_HOW = "`plem validate <package>` lists every problem of the description"


def _robot_geometry(model: pin.Model, urdf_xml: str) -> pin.GeometryModel:
    """The URDF's collision shapes on `model`, with every mesh file found on plem's package search path."""
    root = parse_xml(urdf_xml, URDF_SOURCE)
    missing = []
    for link in root.findall("link"):
        for mesh in link.findall("collision/geometry/mesh"):
            uri = mesh.get("filename") or ""
            try:
                mesh.set("filename", str(resolve_package_uri(uri).absolute()))
            except PlemError as error:
                missing.append(f"link {link.get('name')}: mesh {uri}: {error.why}")
    if missing:
        raise DescriptionError(
            f"{len(missing)} collision mesh{'es' if len(missing) > 1 else ''} of the URDF not found",
            what="every <collision> mesh of the URDF as a file, package:// resolving on the package search path",
            why="\n".join(missing),
            how=f"add the folder of the package holding the meshes to PLEM_PACKAGE_PATH, or fix the file names; "
                f"{VALIDATE_HOW}")
    try:
        return pin.buildGeomFromUrdfString(model, etree.tostring(root, encoding="unicode"), pin.COLLISION)
    except (ValueError, RuntimeError) as error:
        raise DescriptionError(
            "pinocchio could not read the URDF's collision shapes",
            what="<collision> elements of boxes, spheres, cylinders and STL, OBJ or DAE meshes",
            why=" ".join(str(error).split()) or type(error).__name__,
            how=f"fix the <collision> element it names; {VALIDATE_HOW}") from None


def _known(names: Iterable[str]) -> str:
    return ", ".join(names) or "none"


def _triangle_mesh(mesh: TriangleMesh) -> coal.BVHModelOBBRSS:
    """An inline mesh as the bounding volume hierarchy coal builds for a mesh file."""
    model = coal.BVHModelOBBRSS()
    model.beginModel(len(mesh.triangles), len(mesh.vertices))
    model.addVertices(np.array(mesh.vertices, dtype=np.float64))
    model.addTriangles(np.array(mesh.triangles, dtype=np.int64))
    model.endModel()
    return model


class CollisionChecker:
    """Whether a configuration of the arm collides with itself or the planning scene, and which pairs do.

    `q` holds one position per joint of `model` (built by the caller from `urdf_xml`) in pinocchio's joint order
    (`JointSpace`: a continuous joint's angle, unwrapped). One checker is
    not thread-safe: it owns pinocchio's and coal's working data, so each planning thread builds its own.
    """

    def __init__(self, model: pin.Model, urdf_xml: str, disabled_pairs: Iterable[tuple[str, str]]) -> None:
        self._model = model
        self._data = model.createData()
        self._space = JointSpace(model)
        self._robot = _robot_geometry(model, urdf_xml)
        self._links = tuple(frame.name for frame in model.frames if frame.type == pin.FrameType.BODY)
        self._owners = tuple(model.frames[g.parentFrame].name for g in self._robot.geometryObjects)
        self._bodies = tuple(int(g.parentJoint) for g in self._robot.geometryObjects)
        self._robot_pairs = self._self_pairs(self._disabled(disabled_pairs))
        self._meshes = coal.CachedMeshLoader()
        self._scene: PlanningScene | None = None
        self._scene_version = -1
        self._use([], [])

    def link_names(self) -> tuple[str, ...]:
        """The arm's links as the URDF names them: what attached_to, touch_links and `contacts` name."""
        return self._links

    def _disabled(self, pairs: Iterable[tuple[str, str]]) -> set[frozenset[str]]:
        """The SRDF's disabled pairs, each a set of two link names; a link the URDF lacks is a DescriptionError."""
        disabled = {frozenset(pair) for pair in pairs}
        unknown = sorted({link for pair in disabled for link in pair} - set(self._links))
        if unknown:
            raise DescriptionError(
                "the SRDF disables collisions of links the URDF lacks",
                what=f"<disable_collisions> naming links of the URDF ({_known(self._links)})",
                why=f"unknown links: {', '.join(unknown)}",
                how=f"fix or remove those <disable_collisions> in the SRDF; {VALIDATE_HOW}")
        return disabled

    def _adjacent(self, body: int, other: int) -> bool:
        """Whether a joint joins the two rigid bodies directly."""
        parents = self._model.parents
        return bool(parents[body] == other or parents[other] == body)

    def _self_pairs(self, disabled: set[frozenset[str]]) -> list[tuple[int, int]]:
        """Pairs of the robot's shapes to check: on different bodies, not adjacent, not disabled by the SRDF."""
        count = len(self._owners)
        return [(i, j) for i in range(count) for j in range(i + 1, count)
                if self._bodies[i] != self._bodies[j] and not self._adjacent(self._bodies[i], self._bodies[j])
                and frozenset((self._owners[i], self._owners[j])) not in disabled]

    def set_scene(self, scene: PlanningScene) -> None:
        """Check against `scene`'s world and attached objects from now on (a no-op while its version is unchanged).

        A problem of any object (an unknown link or frame, a mesh that cannot be read) is a SceneError, and the
        checker keeps the scene it had."""
        if scene is self._scene and scene.version == self._scene_version:
            return
        objects = scene.objects()
        problems: list[SceneError] = []
        shapes = []
        for obj in objects:
            try:
                shapes.append(self._geometry_object(obj))
            except SceneError as error:
                problems.append(error)
        if len(problems) == 1:
            raise problems[0]
        if problems:
            raise SceneErrors(problems, "the planning scene")
        self._use(objects, shapes)
        self._scene, self._scene_version = scene, scene.version

    def _frame(self, obj: SceneObject, name: str, role: str, *, fixed: bool) -> pin.Frame:
        """The link frame `name`; a SceneError when it is not a link (or, `fixed`, when it moves with the arm)."""
        if name in self._links:
            frame = self._model.frames[link_frame(self._model, name)]
            if not fixed or frame.parentJoint == 0:
                return frame
            raise SceneError(
                f"object {obj.name} is placed in link {name}, which moves", what=f"{role}: world or a link fixed to it",
                why=f"{name} moves with the arm, so a pose in it would change as the arm moves",
                how=f"give the pose in the world (frame: {WORLD}), or attach the object (attached_to: {name})")
        links = [link for link in self._links
                 if not fixed or self._model.frames[link_frame(self._model, link)].parentJoint == 0]
        raise SceneError(f"object {obj.name} names an unknown link {name}",
                         what=f"{role}: {'world or ' if fixed else ''}a link of the arm ({_known(links)})",
                         why=f"{role} is {name}", how=f"name one of the links listed in {role}")

    def _geometry_object(self, obj: SceneObject) -> pin.GeometryObject:
        """`obj` as a pinocchio shape on the body that carries it, placed in that body's joint frame."""
        if obj.name in self._links:
            raise SceneError(f"object {obj.name} has the name of a link", what="object names that are no link's",
                             why=f"the arm has a link {obj.name}, and collisions name both by name",
                             how="rename the object")
        pose = pin.XYZQUATToSE3(np.array([*obj.pose.position, *obj.pose.orientation]))
        if obj.attached_to is None:
            frame_id, placement = 0, pose
            if obj.frame != WORLD or WORLD in self._links:
                frame_id = link_frame(self._model, self._frame(obj, obj.frame, "frame", fixed=True).name)
                placement = self._model.frames[frame_id].placement * pose
            joint = 0
        else:
            for link in obj.touch_links:
                self._frame(obj, link, "touch_links", fixed=False)
            frame = self._frame(obj, obj.attached_to, "attached_to", fixed=False)
            frame_id = link_frame(self._model, frame.name)
            joint, placement = frame.parentJoint, frame.placement * pose
        return pin.GeometryObject(obj.name, joint, frame_id, placement, self._shape(obj, obj.shape))

    def _shape(self, obj: SceneObject, shape: Shape) -> coal.CollisionGeometry:
        """The coal shape of `shape`; a mesh is loaded once per file and scale."""
        if isinstance(shape, Box):
            return coal.Box(*shape.size)
        if isinstance(shape, Cylinder):
            return coal.Cylinder(shape.radius, shape.length)
        if isinstance(shape, Sphere):
            return coal.Sphere(shape.radius)
        if isinstance(shape, TriangleMesh):
            return _triangle_mesh(shape)
        try:
            path = resolve_package_uri(shape.path)
            return self._meshes.load(str(path.absolute()), np.array(shape.scale))
        except PlemError as error:
            why = error.why
        except (ValueError, RuntimeError) as error:  # coal's message follows "message:", after where in coal
            message = str(error).partition("message:")[2].partition("Hint:")[0]
            why = " ".join(message.split()) or " ".join(str(error).split())
        raise SceneError(f"the mesh of object {obj.name} cannot be read", what="an STL, OBJ or DAE mesh file",
                         why=why, how=f"fix the mesh path of object {obj.name} (mesh: {{path: FILE}}), or add the "
                                      f"folder of the package holding it to PLEM_PACKAGE_PATH")

    def _use(self, objects: Sequence[SceneObject], shapes: Sequence[pin.GeometryObject]) -> None:
        """Rebuild the shapes, the pairs to check and the broad phase for the robot plus `objects` (as `shapes`)."""
        geometry = pin.GeometryModel()
        for shape in (*self._robot.geometryObjects, *shapes):
            geometry.addGeometryObject(shape)
        robot = len(self._owners)
        owners = (*self._owners, *(obj.name for obj in objects))
        pairs = list(self._robot_pairs)
        for k, obj in enumerate(objects):
            index = robot + k
            allowed = obj.allowed_links()
            pairs += [(i, index) for i in range(robot) if self._owners[i] not in allowed]
            if obj.attached_to is not None:
                pairs += [(min(robot + m, index), max(robot + m, index)) for m in range(len(objects))
                          if m != k and (objects[m].attached_to is None
                                         or (m < k and shapes[m].parentJoint != shapes[k].parentJoint))]
        for i, j in pairs:
            geometry.addCollisionPair(pin.CollisionPair(i, j))
        geometry_data = pin.GeometryData(geometry)
        with warnings.catch_warnings():  # coal deprecates the switch that pinocchio turns on, which is still obeyed
            warnings.simplefilter("ignore", DeprecationWarning)
            for request in geometry_data.collisionRequests:
                request.enable_cached_gjk_guess = False
        self._geometry, self._geometry_data = geometry, geometry_data
        self._broad_phase = pin.BroadPhaseManager_DynamicAABBTreeCollisionManager(self._model, geometry, geometry_data)
        self._pair_names = [(owners[i], owners[j]) for i, j in pairs]

    def is_free(self, q: np.ndarray) -> bool:
        """Whether the arm at `q` touches neither itself nor the scene; stops at the first collision found."""
        return not pin.computeCollisions(self._model, self._data, self._broad_phase, self._space.configuration(q),
                                         True)

    def contacts(self, q: np.ndarray) -> list[tuple[str, str]]:
        """Every colliding pair at `q`, each once, by link name and object name (link first)."""
        pin.computeCollisions(self._model, self._data, self._geometry, self._geometry_data,
                              self._space.configuration(q), False)
        results = self._geometry_data.collisionResults
        return list(dict.fromkeys(self._pair_names[k] for k in range(len(self._pair_names))
                                  if results[k].isCollision()))
