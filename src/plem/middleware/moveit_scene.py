"""MoveIt's planning-scene messages as plem's scene, and back: collision objects, attached objects, their shapes.

One shape per object (plem's scene holds one); ADD, REMOVE, APPEND (to a new object) and MOVE for world
objects, attach and detach for attached ones. A change that cannot be applied as asked is refused with a
PlanningError or SceneError that names it; a whole planning scene message applies entirely or not at all
(the caller applies it to a copy first).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from plem.core.paths import resolve_package_uri
from plem.errors import MoveItCode, PlanningError, PlemError
from plem.middleware.moveit_messages import pose_from_message, pose_message, refused
from plem.middleware.types import InterfaceLibrary
from plem.planning.planner import Planner, placement_of, pose_of
from plem.planning.poses import Pose
from plem.planning.scene import (
    WORLD,
    Box,
    Cylinder,
    Mesh,
    PlanningScene,
    SceneError,
    SceneObject,
    Shape,
    Sphere,
    TriangleMesh,
)

#: moveit_msgs/CollisionObject operations.
ADD, REMOVE, APPEND, MOVE = 0, 1, 2, 3
#: shape_msgs/SolidPrimitive types and the dimensions each takes.
PRIMITIVES = {1: ("BOX", 3), 2: ("SPHERE", 1), 3: ("CYLINDER", 2), 4: ("CONE", 2), 5: ("PRISM", 1)}
#: moveit_msgs/PlanningSceneComponents bits plem answers.
SCENE_SETTINGS, ROBOT_STATE, ATTACHED_OBJECTS, OBJECT_NAMES, OBJECT_GEOMETRY, OBJECT_COLORS = 1, 2, 4, 8, 16, 512


def shape_from_message(message: Any) -> tuple[Shape, Pose]:
    """The one shape of a moveit_msgs/CollisionObject and its pose relative to the object's pose."""
    name = message.id
    if message.planes or message.plane_poses:
        raise refused(f"the planes of object {name!r}", "plem's planning scene holds no infinite planes",
                      "give a thin box instead of a plane")
    if message.subframe_names or message.subframe_poses:
        raise refused(f"the subframes of object {name!r}", "plem's planning scene names no subframes",
                      "leave subframe_names and subframe_poses empty")
    count = len(message.primitives) + len(message.meshes)
    if count != 1 or len(message.primitive_poses) > len(message.primitives) \
            or len(message.mesh_poses) > len(message.meshes):
        raise SceneError(f"object {name!r} does not have one shape",
                         what="one primitive or one mesh per object (and at most one pose for it)",
                         why=f"{len(message.primitives)} primitives with {len(message.primitive_poses)} poses, "
                             f"{len(message.meshes)} meshes with {len(message.mesh_poses)} poses",
                         how="give each shape an object (id) of its own")
    if message.primitives:
        shape, poses = _primitive(name, message.primitives[0]), message.primitive_poses
    else:
        shape, poses = _mesh(message.meshes[0]), message.mesh_poses
    return shape, pose_from_message(poses[0]) if poses else Pose()


def _primitive(name: str, primitive: Any) -> Shape:
    kind, count = PRIMITIVES.get(primitive.type, (str(primitive.type), 0))
    dimensions = [float(value) for value in primitive.dimensions]
    if kind not in ("BOX", "SPHERE", "CYLINDER"):
        raise refused(f"the {kind} primitive of object {name!r}", "plem's planning scene has boxes, spheres, "
                      "cylinders and meshes", "give the object as a BOX, SPHERE or CYLINDER, or as a mesh",
                      what="a BOX (1), SPHERE (2) or CYLINDER (3) primitive, or a mesh")
    if len(dimensions) != count:
        raise SceneError(f"the {kind} of object {name!r} has {len(dimensions)} dimensions",
                         what=f"{count} dimensions for a {kind} (shape_msgs/SolidPrimitive)",
                         why=f"dimensions: {dimensions}",
                         how="BOX: [x, y, z], SPHERE: [radius], CYLINDER: [height, radius], in metres")
    if kind == "BOX":
        return Box((dimensions[0], dimensions[1], dimensions[2]))
    if kind == "SPHERE":
        return Sphere(dimensions[0])
    return Cylinder(radius=dimensions[1], length=dimensions[0])


def _mesh(mesh: Any) -> TriangleMesh:
    return TriangleMesh(tuple((p.x, p.y, p.z) for p in mesh.vertices),
                        tuple(tuple(triangle.vertex_indices) for triangle in mesh.triangles))


def collision_object_message(library: InterfaceLibrary, obj: SceneObject, frame_id: str, *, geometry: bool = True,
                             object_type: Any = None) -> Any:
    """moveit_msgs/CollisionObject of a scene object at its pose in `frame_id`: its id alone, or with its shape."""
    fields: dict[str, Any] = {"id": obj.name, "operation": ADD}
    if object_type is not None:
        fields["type"] = object_type
    if geometry:
        identity = pose_message(library, Pose())
        fields.update(header=library.new("std_msgs/msg/Header", frame_id=frame_id),
                      pose=pose_message(library, obj.pose))
        if isinstance(obj.shape, (Mesh, TriangleMesh)):
            fields.update(meshes=[_mesh_message(library, obj.shape)], mesh_poses=[identity])
        else:
            fields.update(primitives=[_primitive_message(library, obj.shape)], primitive_poses=[identity])
    return library.new("moveit_msgs/msg/CollisionObject", **fields)


def _primitive_message(library: InterfaceLibrary, shape: Box | Sphere | Cylinder) -> Any:
    if isinstance(shape, Box):
        kind, dimensions = 1, list(shape.size)
    elif isinstance(shape, Sphere):
        kind, dimensions = 2, [shape.radius]
    else:
        kind, dimensions = 3, [shape.length, shape.radius]
    return library.new("shape_msgs/msg/SolidPrimitive", type=kind, dimensions=dimensions)


def _mesh_message(library: InterfaceLibrary, shape: Mesh | TriangleMesh) -> Any:
    mesh = shape if isinstance(shape, TriangleMesh) else mesh_file_triangles(shape.path, shape.scale)
    new = library.new
    return new("shape_msgs/msg/Mesh",
               triangles=[new("shape_msgs/msg/MeshTriangle", vertex_indices=list(t)) for t in mesh.triangles],
               vertices=[new("geometry_msgs/msg/Point", x=x, y=y, z=z) for x, y, z in mesh.vertices])


@lru_cache(maxsize=16)
def mesh_file_triangles(path: str, scale: tuple[float, float, float]) -> TriangleMesh:
    """The triangles of a mesh file (STL, OBJ, DAE), scaled, as shape_msgs/Mesh carries them; a SceneError when the
    file cannot be read."""
    try:
        model = coal.MeshLoader().load(str(resolve_package_uri(path).absolute()), np.array(scale))
    except PlemError as error:
        raise SceneError(f"the mesh {path} cannot be read", what="an STL, OBJ or DAE mesh file", why=error.why,
                         how="fix the object's mesh path (plem scene), or add the folder of the package holding it to "
                             "PLEM_PACKAGE_PATH") from None
    except (ValueError, RuntimeError) as error:
        raise SceneError(f"the mesh {path} cannot be read", what="an STL, OBJ or DAE mesh file",
                         why=" ".join(str(error).split())[:300], how="fix the mesh file") from None
    vertices = tuple(tuple(map(float, row)) for row in np.asarray(model.vertices()))
    triangles = tuple((int(t[0]), int(t[1]), int(t[2])) for t in map(model.tri_indices, range(model.num_tris)))
    return TriangleMesh(vertices, triangles)  # type: ignore[arg-type]  # rows of three, as the model holds them


# -- planning scenes -------------------------------------------------------------------------------------
def check_scene_message(scene: Any) -> None:
    """Refuse what a moveit_msgs/PlanningScene may set that plem's planning scene does not hold."""
    how = "leave it empty: plem's scene holds collision objects, attached objects and their colors"
    if scene.fixed_frame_transforms:
        raise refused("fixed_frame_transforms", "plem's frames are the URDF's links", how)
    matrix = scene.allowed_collision_matrix
    if matrix.entry_names or matrix.default_entry_names:
        raise refused("allowed_collision_matrix", "plem takes the pairs never checked from the SRDF's "
                      "<disable_collisions> and from touch_links", f"{how}; attach objects with touch_links, or add "
                      "<disable_collisions> to the SRDF")
    if scene.link_padding or scene.link_scale:
        raise refused("link_padding and link_scale", "plem checks the URDF's collision shapes as they are",
                      f"{how}; enlarge the <collision> shapes in the URDF instead")
    if scene.world.octomap.octomap.data or scene.world.octomap.octomap.id:
        raise refused("world.octomap", "plem's planning scene holds no octomap",
                      "give the obstacles as collision objects (boxes, meshes)")
    state = scene.robot_state
    multi = state.multi_dof_joint_state
    if state.joint_state.name or state.joint_state.position or multi.joint_names or multi.transforms:
        raise refused("robot_state joint positions", "plem's scene follows the arm's measured state",
                      "leave robot_state.joint_state and multi_dof_joint_state empty; give a start state in the "
                      "planning request instead")


def check_attached(message: Any) -> None:
    """Refuse what an AttachedCollisionObject may carry that plem does not use: a detach posture, a weight."""
    name = message.object.id
    posture = message.detach_posture
    if posture.joint_names or posture.points:
        raise refused(f"the detach_posture of object {name!r}", "plem moves no gripper when an object is detached",
                      "leave detach_posture empty and move the gripper yourself")
    if message.weight != 0.0:
        raise refused(f"the weight of object {name!r}", "plem's arm model takes no payload from the scene",
                      "leave weight at 0")


def has_shapes(message: Any) -> bool:
    """Whether a CollisionObject message carries geometry."""
    return bool(message.primitives or message.meshes or message.planes)


def apply_scene(planner: Planner, positions: Sequence[float], message: Any) -> None:
    """Apply a moveit_msgs/PlanningScene (checked by `check_scene_message`) to the planner's scene with the arm at
    `positions`: every change, or none when one fails (its error raised)."""
    scene = planner.scene
    before = scene.objects()
    state = message.robot_state
    listing = not message.is_diff or (not state.is_diff and bool(state.attached_collision_objects))
    try:
        for obj in scene.objects():
            if not message.is_diff or (listing and obj.attached_to is not None):  # a state that is no diff lists
                scene.remove(obj.name)                                              # every attached object
        for change in message.world.collision_objects:
            world_change(planner, positions, change)
        for change in state.attached_collision_objects:
            attached_change(planner, positions, change, listing)
        planner.collisions.set_scene(scene)  # every object is checked before the change is kept
    except PlemError:
        for obj in scene.objects():
            scene.remove(obj.name)
        for obj in before:
            scene.add(obj)
        raise


def frame_placement(planner: Planner, positions: Sequence[float], frame: str) -> pin.SE3:
    """Where `frame` (a link, 'world' or '') is in the root frame at `positions`."""
    try:
        return planner.link_pose(positions, frame)
    except PlanningError as error:
        raise PlanningError(f"unknown frame {frame!r}", what=error.what, why=error.why,
                            how="give header.frame_id as a link of the URDF, 'world', or leave it empty",
                            code=MoveItCode.FRAME_TRANSFORM_FAILURE) from None

def world_change(planner: Planner, positions: Sequence[float], change: Any) -> None:
    """One world CollisionObject's operation, applied to the scene."""
    scene, name = planner.scene, change.id
    names = {obj.name: obj for obj in scene.objects()}
    if change.operation in (ADD, APPEND):
        if change.operation == APPEND and name in names:
            raise refused(f"APPEND to object {name!r}", "plem's planning scene holds one shape per object",
                          "give the new shape an object (id) of its own")
        shape, placement = _shape_placement(change)
        frame = frame_placement(planner, positions, change.header.frame_id)
        scene.add(SceneObject(name, shape, pose_of(frame * placement)))
    elif change.operation == REMOVE:
        if not name:
            for obj in names.values():
                if obj.attached_to is None:
                    scene.remove(obj.name)
        elif name in names and names[name].attached_to is not None:
            raise _not_in_world(scene, name)
        else:
            scene.remove(name)
    elif change.operation == MOVE:
        obj = scene.get(name)
        if obj.attached_to is not None:
            raise _not_in_world(scene, name)
        if has_shapes(change):
            raise refused(f"the shapes of MOVE for object {name!r}", "MOVE changes the pose alone",
                          "send the new shape with ADD")
        offset = list(change.primitive_poses) + list(change.mesh_poses)
        placement = placement_of(pose_from_message(change.pose))
        if offset:
            placement = placement * placement_of(pose_from_message(offset[0]))
        frame = frame_placement(planner, positions, change.header.frame_id)
        scene.add(dataclasses.replace(obj, pose=pose_of(frame * placement), frame=WORLD))
    else:
        raise _unknown_operation(name, change.operation)

def attached_change(planner: Planner, positions: Sequence[float], change: Any, listing: bool) -> None:
    """One AttachedCollisionObject's operation: attach (a world object, or a new one) or detach."""
    check_attached(change)
    scene, obj = planner.scene, change.object
    names = {item.name: item for item in scene.objects()}
    if listing and obj.operation != ADD:
        raise refused(f"operation {obj.operation} on attached object {obj.id!r} in a robot state that is no diff",
                      "a robot_state with is_diff false lists every attached object, so only ADD applies",
                      "set robot_state.is_diff to true to attach or detach single objects")
    if obj.operation in (ADD, APPEND):
        link = planner.link_name(change.link_name)
        touch = tuple(planner.link_name(name) for name in change.touch_links)
        holder = planner.link_pose(positions, link)
        if obj.operation == APPEND and obj.id in names:
            raise refused(f"APPEND to object {obj.id!r}", "plem's planning scene holds one shape per object",
                          "give the new shape an object (id) of its own")
        if not has_shapes(obj):
            if scene.get(obj.id).attached_to is not None:
                raise _not_in_world(scene, obj.id)
            planner.attach(obj.id, link, touch, positions)
            return
        shape, placement = _shape_placement(obj)
        frame = obj.header.frame_id
        if frame and planner.link_name(frame) != link:
            placement = holder.actInv(frame_placement(planner, positions, frame) * placement)
        scene.add(SceneObject(obj.id, shape, pose_of(placement), attached_to=link, touch_links=touch))
    elif obj.operation == REMOVE:
        holder_link = planner.link_name(change.link_name) if change.link_name else None
        held = [item for item in names.values() if item.attached_to is not None
                and (not obj.id or item.name == obj.id) and (holder_link in (None, item.attached_to))]
        if obj.id and not held:
            raise SceneError(f"object {obj.id!r} is not attached{f' to {holder_link}' if holder_link else ''}",
                             what="the id of an attached object (and its link, or an empty link_name)",
                             why="attached: " + (", ".join(f"{item.name} to {item.attached_to}"
                                                           for item in names.values() if item.attached_to)
                                                 or "nothing"),
                             how="name an attached object; get_planning_scene lists them")
        for item in held:
            planner.detach(item.name, positions)
    else:
        raise _unknown_operation(obj.id, obj.operation) if obj.operation != MOVE else refused(
            f"MOVE of attached object {obj.id!r}", "an attached object moves with its link (nor does MoveIt "
            "move attached objects)", "detach it, MOVE it, and attach it again")


def _not_in_world(scene: PlanningScene, name: str) -> SceneError:
    """The error for an operation on a world object that is not one (absent, or attached)."""
    world = ", ".join(obj.name for obj in scene.objects() if obj.attached_to is None) or "none"
    return SceneError(f"no world object named {name!r}", what="the id of a world object",
                      why=f"world objects: {world}", how="name a world object; get_planning_scene lists them; "
                                                          "detach an attached object first")


def _unknown_operation(name: str, operation: int) -> SceneError:
    return SceneError(f"unknown operation {operation} for object {name!r}", what="ADD (0), REMOVE (1), APPEND (2) or "
                      "MOVE (3)", why=f"operation is {operation}", how="set operation to one of those")


def _shape_placement(change: Any) -> tuple[Shape, pin.SE3]:
    """A CollisionObject's shape, and its placement in the object's header frame."""
    shape, offset = shape_from_message(change)
    return shape, placement_of(pose_from_message(change.pose)) * placement_of(offset)
