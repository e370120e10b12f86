"""The planning scene: named boxes, spheres, cylinders and meshes in the world or held by a link of the arm.

Pure data, as MoveIt's PlanningScene world and attached objects are: lengths in metres, poses as a position
and a unit quaternion (x, y, z, w). A world object's pose is in `frame` ("world", the URDF's root link, or a
link fixed to it); an attached object's pose is relative to the link it is attached to and moves with it.
The scene serialises to plain dicts and lists (`to_json`) in the form a scene file's entries take:

```yaml
objects:
  - name: table
    box: [1.2, 0.8, 0.05]          # or sphere: 0.1 / cylinder: {radius: 0.05, length: 0.3}
                                    # or mesh: {path: FILE or package://..., scale: [1, 1, 1]}
                                    # or mesh: {vertices: [[x, y, z], ...], triangles: [[0, 1, 2], ...]}
    position: [0.5, 0.0, -0.03]
    orientation: [0, 0, 0, 1]       # optional, x y z w
    frame: world                    # optional
    attached_to: tcp                # optional
    touch_links: [link6]            # optional
```
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeGuard, TypeVar

import numpy as np

from plem.core.config.yaml_document import YamlSyntaxError, read_yaml
from plem.core.paths import resolve_package_uri
from plem.errors import MultipleErrors, PlemError
from plem.planning.poses import Pose

#: The frame of world objects unless they name another: the URDF's root link.
WORLD = "world"
#: The longest name of an object or link the scene accepts.
MAX_NAME = 256
#: Keys of an object's entry in a scene file or in `to_json`, and the shape keys among them.
SHAPE_KEYS = ("box", "sphere", "cylinder", "mesh")
OBJECT_KEYS = ("name", *SHAPE_KEYS, "position", "orientation", "frame", "attached_to", "touch_links")
ENTRY_HOW = ("write each object as a mapping: name, one of box: [x, y, z], sphere: RADIUS, "
             "cylinder: {radius: R, length: L}, mesh: {path: FILE, scale: [x, y, z]} or "
             "mesh: {vertices: [[x, y, z], ...], triangles: [[i, j, k], ...]}, and position: [x, y, z]")
#: Most vertices, and most triangles, a mesh given inline may have.
MAX_MESH_ELEMENTS = 1_000_000
NO_LINKS: tuple[str, ...] = ()
ONES = (1.0, 1.0, 1.0)
T = TypeVar("T")


class SceneError(PlemError):
    """A planning scene object, file or request is invalid, or names an object the scene does not hold."""


class SceneErrors(MultipleErrors, SceneError):
    """Several problems of one scene file or request, reported together."""


def _shown(value: object, limit: int = 60) -> str:
    """`repr(value)`, shortened to `limit` characters so a huge value cannot flood a message."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _is_number(value: object) -> TypeGuard[float]:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _numbers(label: str, value: object, count: int, how: str) -> tuple[float, ...]:
    """`value` as `count` finite numbers, or a SceneError naming `label`."""
    if (isinstance(value, (list, tuple)) and len(value) == count and all(_is_number(v) for v in value)
            and all(math.isfinite(v) for v in value)):
        return tuple(float(v) for v in value)
    raise SceneError(f"{label} is not {count} finite numbers", what=f"{label} as {count} finite numbers",
                     why=f"{label} is {_shown(value)}", how=how)


def _positive(label: str, value: object, how: str) -> float:
    """`value` as a finite number above zero (a size in metres), or a SceneError naming `label`."""
    if _is_number(value) and math.isfinite(value) and value > 0:
        return float(value)
    raise SceneError(f"{label} is not a size above zero", what=f"{label} as a finite number of metres above zero",
                     why=f"{label} is {_shown(value)}", how=how)


def _name(label: str, value: object) -> str:
    """`value` when it is a usable object or link name (non-empty, printable, at most MAX_NAME characters)."""
    if isinstance(value, str) and value and value.isprintable() and len(value) <= MAX_NAME:
        return value
    raise SceneError(f"{label} is not a valid name",
                     what=f"{label} as a non-empty text of at most {MAX_NAME} printable characters",
                     why=f"{label} is {_shown(value)}", how=f"give {label} a short printable name")


@dataclass(frozen=True)
class Box:
    """A box centred on its pose, with edge lengths (x, y, z) in metres."""

    size: tuple[float, float, float]

    def __post_init__(self) -> None:
        how = "give the box three edge lengths in metres, each above zero (box: [x, y, z])"
        sizes = _numbers("box", self.size, 3, how)
        object.__setattr__(self, "size", tuple(_positive("box size", v, how) for v in sizes))


@dataclass(frozen=True)
class Sphere:
    """A sphere centred on its pose, of `radius` metres."""

    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", _positive("sphere radius", self.radius, "write sphere: RADIUS in metres"))


@dataclass(frozen=True)
class Cylinder:
    """A cylinder centred on its pose with its axis along z, as ROS's SolidPrimitive: radius and length in metres."""

    radius: float
    length: float

    def __post_init__(self) -> None:
        how = "write cylinder: {radius: R, length: L} in metres"
        object.__setattr__(self, "radius", _positive("cylinder radius", self.radius, how))
        object.__setattr__(self, "length", _positive("cylinder length", self.length, how))


@dataclass(frozen=True)
class Mesh:
    """A mesh file (STL, OBJ, DAE) by path or `package://` URI, its vertices scaled by (x, y, z)."""

    path: str
    scale: tuple[float, float, float] = ONES

    def __post_init__(self) -> None:
        if not isinstance(self.path, str) or not self.path or "\0" in self.path:
            raise SceneError("mesh path is not a file name", what="mesh path as a file path or package:// URI",
                             why=f"path is {_shown(self.path)}", how="write mesh: {path: FILE} naming an STL, OBJ or "
                             "DAE file")
        how = "write mesh scale: [x, y, z], each above zero ([1, 1, 1] keeps the file's size)"
        scales = _numbers("mesh scale", self.scale, 3, how)
        object.__setattr__(self, "scale", tuple(_positive("mesh scale", v, how) for v in scales))


@dataclass(frozen=True)
class TriangleMesh:
    """A mesh given inline, as shape_msgs/Mesh carries it: vertices (x, y, z) in metres, and triangles as three
    indices into the vertices each."""

    vertices: tuple[tuple[float, float, float], ...]
    triangles: tuple[tuple[int, int, int], ...]

    def __post_init__(self) -> None:
        how = "give the mesh vertices as [x, y, z] in metres and its triangles as three vertex indices each"
        vertices = _rows("mesh vertices", self.vertices, how)
        triangles = _rows("mesh triangles", self.triangles, how)
        if not (np.all(triangles == np.round(triangles)) and triangles.min() >= 0
                and triangles.max() < len(vertices)):
            raise SceneError("mesh triangles are not indices of its vertices",
                             what=f"three whole numbers from 0 to {len(vertices) - 1} per triangle",
                             why=f"indices range from {triangles.min():g} to {triangles.max():g}", how=how)
        object.__setattr__(self, "vertices", tuple(map(tuple, vertices.tolist())))
        object.__setattr__(self, "triangles", tuple(map(tuple, triangles.astype(np.int64).tolist())))


def _rows(label: str, value: object, how: str) -> np.ndarray:
    """`value` as rows of three finite numbers (at least one, at most MAX_MESH_ELEMENTS), or a SceneError."""
    try:
        rows = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        rows = np.empty((0, 0))
    if rows.ndim == 2 and rows.shape[1] == 3 and 0 < len(rows) <= MAX_MESH_ELEMENTS and np.isfinite(rows).all():
        return rows
    raise SceneError(f"{label} are not rows of three finite numbers",
                     what=f"{label} as 1 to {MAX_MESH_ELEMENTS} rows of three finite numbers",
                     why=f"{label} are {_shown(value)}", how=how)


Shape = Box | Sphere | Cylinder | Mesh | TriangleMesh


@dataclass(frozen=True)
class SceneObject:
    """A named shape at `pose` in `frame`, or, when `attached_to` names a link, held by that link at `pose`.

    `touch_links` are links an attached object may touch besides the one holding it. An attached object's
    frame is the link it is attached to."""

    name: str
    shape: Shape
    pose: Pose = field(default_factory=Pose)
    frame: str = WORLD
    attached_to: str | None = None
    touch_links: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        _name("name", self.name)
        if not isinstance(self.shape, (Box, Sphere, Cylinder, Mesh, TriangleMesh)):
            raise SceneError(f"object {self.name} has no shape", what="a box, sphere, cylinder or mesh",
                             why=f"the shape is {_shown(self.shape)}", how=ENTRY_HOW)
        if not isinstance(self.pose, Pose):
            raise SceneError(f"object {self.name} has no pose", what="a position and an orientation",
                             why=f"the pose is {_shown(self.pose)}", how="write position: [x, y, z]")
        _name("frame", self.frame)
        if self.attached_to is not None:
            _name("attached_to", self.attached_to)
            if self.frame not in (WORLD, self.attached_to):
                raise SceneError(
                    f"attached object {self.name} gives its pose in another frame",
                    what=f"the pose of an object attached to {self.attached_to} relative to {self.attached_to}",
                    why=f"frame is {self.frame}, attached_to is {self.attached_to}",
                    how="leave frame out for an attached object, or set it to the link in attached_to")
            object.__setattr__(self, "frame", self.attached_to)
        object.__setattr__(self, "touch_links", _links(self.touch_links))
        if self.touch_links and self.attached_to is None:
            raise SceneError(f"world object {self.name} has touch links",
                             what="touch_links only on an object attached to a link",
                             why=f"touch_links is {list(self.touch_links)}, attached_to is not set",
                             how="leave touch_links out, or attach the object (attached_to: LINK)")

    def allowed_links(self) -> frozenset[str]:
        """Links this object is never checked against: the one holding it and its touch links (none in the world)."""
        return frozenset((self.attached_to, *self.touch_links)) if self.attached_to is not None else frozenset()

    def to_json(self) -> dict[str, Any]:
        """The object as a scene file's entry: plain dicts, lists, numbers and text."""
        entry: dict[str, Any] = {"name": self.name, **_shape_entry(self.shape),
                                 "position": list(self.pose.position), "orientation": list(self.pose.orientation),
                                 "frame": self.frame}
        if self.attached_to is not None:
            entry["attached_to"] = self.attached_to
            entry["touch_links"] = list(self.touch_links)
        return entry


def _links(value: object) -> tuple[str, ...]:
    """Link names (touch_links) without repeats, each a valid name."""
    if not isinstance(value, (list, tuple)):
        raise SceneError("touch_links is not a list", what="touch_links as a list of link names",
                         why=f"touch_links is {_shown(value)}", how="write touch_links: [link, ...]")
    return tuple(dict.fromkeys(_name("touch_links entry", link) for link in value))


def _shape_entry(shape: Shape) -> dict[str, Any]:
    if isinstance(shape, Box):
        return {"box": list(shape.size)}
    if isinstance(shape, Sphere):
        return {"sphere": shape.radius}
    if isinstance(shape, Cylinder):
        return {"cylinder": {"radius": shape.radius, "length": shape.length}}
    if isinstance(shape, TriangleMesh):
        return {"mesh": {"vertices": [list(v) for v in shape.vertices],
                         "triangles": [list(t) for t in shape.triangles]}}
    return {"mesh": {"path": shape.path, "scale": list(shape.scale)}}


class PlanningScene:
    """The objects a motion must not hit, by name; `version` increases on every change so users can tell.

    A change replaces the table of objects rather than editing it, so that a reader in another thread (the
    planner's answers to views while it plans) always sees a whole table.
    """

    def __init__(self, objects: Iterable[SceneObject] = (), version: int = 0) -> None:
        self._objects: dict[str, SceneObject] = {obj.name: obj for obj in objects}
        self._version = version

    @property
    def version(self) -> int:
        """How many changes the scene has seen (or the version it was restored with, plus its changes since)."""
        return self._version

    def objects(self) -> tuple[SceneObject, ...]:
        """Every object, world and attached, in the order they were first added."""
        return tuple(self._objects.values())

    def get(self, name: str) -> SceneObject:
        """The object called `name`; a SceneError listing the known names when there is none."""
        found = self._objects.get(name)
        if found is None:
            known = ", ".join(self._objects) or "none, the scene is empty"
            raise SceneError(f"no object named {_shown(name)} in the planning scene",
                             what="the name of an object in the planning scene", why=f"known objects: {known}",
                             how="name one of the known objects (get_planning_scene lists them), or add the object "
                                 "first")
        return found

    def _set(self, obj: SceneObject) -> None:
        self._objects = {**self._objects, obj.name: obj}
        self._version += 1

    def add(self, obj: SceneObject) -> None:
        """Add `obj`, replacing an object of the same name (as MoveIt's ADD does)."""
        self._set(obj)

    def move(self, name: str, pose: Pose) -> None:
        """Put object `name` at `pose`, in the frame it is already in (its link's, when attached)."""
        self._set(dataclasses.replace(self.get(name), pose=pose))

    def remove(self, name: str) -> None:
        """Remove object `name`, world or attached."""
        self.get(name)
        self._objects = {key: obj for key, obj in self._objects.items() if key != name}
        self._version += 1

    def attach(self, name: str, link: str, pose_in_link: Pose, touch_links: Iterable[str] = ()) -> None:
        """Make object `name` move with `link`, held at `pose_in_link`; it may touch `link` and `touch_links`."""
        links = (touch_links,) if isinstance(touch_links, str) else tuple(touch_links)
        self._set(dataclasses.replace(self.get(name), pose=pose_in_link, frame=link, attached_to=link,
                                      touch_links=links))

    def detach(self, name: str, pose_in_world: Pose) -> None:
        """Leave attached object `name` in the world at `pose_in_world` (where its link holds it now)."""
        obj = self.get(name)
        if obj.attached_to is None:
            attached = ", ".join(o.name for o in self._objects.values() if o.attached_to is not None) or "none"
            raise SceneError(f"object {name} is not attached", what="the name of an attached object",
                             why=f"{name} is a world object; attached objects: {attached}",
                             how="detach one of the attached objects, or move the world object instead")
        self._set(dataclasses.replace(obj, pose=pose_in_world, frame=WORLD, attached_to=None, touch_links=()))

    def to_json(self) -> dict[str, Any]:
        """The scene as plain dicts and lists: its version and every object as a scene file's entry."""
        version = self._version  # before the objects: a reader never pairs an old table with a new version
        return {"version": version, "objects": [obj.to_json() for obj in self._objects.values()]}

    @classmethod
    def from_json(cls, data: Any) -> PlanningScene:
        """The scene `to_json` gave; any problem in `data` is a SceneError naming where it is."""
        reader = _Reader(_json_place, base=None)
        if not isinstance(data, Mapping):
            raise SceneError("the planning scene is not a mapping", what="{version: N, objects: [...]}",
                             why=f"it is {_shown(data)}", how=ENTRY_HOW)
        version = data.get("version", 0)
        if not (isinstance(version, int) and not isinstance(version, bool) and version >= 0):
            reader.problem(("version",), "version is not a count", "version as a whole number, 0 or more",
                           f"version is {_shown(version)}", "give the version to_json gave, or leave it out")
            version = 0
        objects = reader.objects(data, ("version", "objects"))
        reader.raise_problems("the planning scene")
        return cls(objects, version)


def _json_place(keys: tuple[str | int, ...]) -> str:
    """Where `keys` point in a JSON scene: `objects[2].box`, or `the scene` for the top level."""
    return "".join(f"[{key}]" if isinstance(key, int) else f".{key}" for key in keys).lstrip(".") or "the scene"


def read_scene_file(path: str | Path) -> list[SceneObject]:
    """The objects a scene file lists; every problem in the file is reported together, each with its line."""
    path = Path(path).expanduser()
    try:
        document = read_yaml(path, "scene file")
    except PlemError as error:
        summary = (f"the scene file {path} is not valid YAML" if isinstance(error, YamlSyntaxError)
                   else f"cannot read the scene file {path}")
        raise SceneError(summary, what=error.what, why=error.why, how=f"{error.how} (the scene file)") from None
    reader = _Reader(lambda keys: f"{path}:{document.line(*keys)}", base=path.parent)
    if not isinstance(document.root, Mapping):
        raise SceneError(f"{path} lists no objects", what="a top-level objects: list",
                         why=f"{path}: the file holds {_shown(document.root)}", how=ENTRY_HOW)
    objects = reader.objects(document.root, ("objects",))
    reader.raise_problems(str(path))
    return objects


class _Reader:
    """Builds scene objects from plain values, collecting every problem with its place (`place(key path)`)."""

    def __init__(self, place: Callable[[tuple[str | int, ...]], str], base: Path | None) -> None:
        self.place = place
        self.base = base  # relative mesh paths are relative to this folder
        self.problems: list[SceneError] = []

    def problem(self, keys: tuple[str | int, ...], summary: str, what: str, why: str, how: str) -> None:
        """Record a problem at `keys`."""
        self.problems.append(SceneError(summary, what=what, why=f"{self.place(keys)}: {why}", how=how))

    def build(self, keys: tuple[str | int, ...], make: Callable[[], T]) -> T | None:
        """`make()`, or None with its error (a scene's or a pose's) recorded as a SceneError at `keys`."""
        try:
            return make()
        except PlemError as error:
            self.problems.append(SceneError(error.summary, what=error.what, why=f"{self.place(keys)}: {error.why}",
                                            how=error.how))
            return None

    def raise_problems(self, context: str) -> None:
        """Raise nothing, the one problem, or all of them as one SceneErrors."""
        if len(self.problems) == 1:
            raise self.problems[0]
        if self.problems:
            raise SceneErrors(self.problems, context)

    def objects(self, root: Mapping[Any, Any], allowed: Sequence[str]) -> list[SceneObject]:
        """The objects under `objects:` in `root`, whose keys must be among `allowed`."""
        unknown = [str(key) for key in root if key not in allowed]
        if unknown:
            self.problem((unknown[0],), "unknown keys in the scene", f"keys: {', '.join(allowed)}",
                         f"unknown: {', '.join(unknown)}", "remove them, or spell them as listed")
        if "objects" not in root:
            self.problem((), "no objects: key", "a top-level objects: list",
                         f"keys: {', '.join(map(str, root)) or 'none'}", ENTRY_HOW)
            return []
        entries = root["objects"] if root["objects"] is not None else []
        if not isinstance(entries, list):
            self.problem(("objects",), "objects is not a list", "objects: a list of objects",
                         f"objects is {_shown(entries)}", ENTRY_HOW)
            return []
        found: dict[str, int] = {}
        objects = []
        for index, entry in enumerate(entries):
            obj = self.entry(("objects", index), entry)
            name = entry.get("name") if isinstance(entry, Mapping) else None
            if isinstance(name, str) and name in found:
                self.problem(("objects", index, "name"), f"object {name} appears twice",
                             "a distinct name per object", f"objects {found[name]} and {index} are both {name}",
                             "rename one of them")
            elif isinstance(name, str):
                found[name] = index
            if obj is not None:
                objects.append(obj)
        return objects

    def entry(self, keys: tuple[str | int, ...], entry: object) -> SceneObject | None:
        """One object's entry, or None when it has problems (all recorded)."""
        if not isinstance(entry, Mapping):
            self.problem(keys, "an object is not a mapping", "each object as a mapping", f"it is {_shown(entry)}",
                         ENTRY_HOW)
            return None
        before = len(self.problems)
        unknown = [str(key) for key in entry if key not in OBJECT_KEYS]
        if unknown:
            self.problem((*keys, unknown[0]), "unknown keys in an object", f"keys: {', '.join(OBJECT_KEYS)}",
                         f"unknown: {', '.join(unknown)}", "remove them, or spell them as listed")
        for key in ("name", "position"):
            if entry.get(key) is None:
                self.problem(keys, f"an object has no {key}", f"{key}: in every object", f"no {key} given",
                             ENTRY_HOW)
        name = self.checked(keys, entry, "name", lambda v: _name("name", v), None)
        shape = self.shape(keys, entry)
        at = self.checked(keys, entry, "position", lambda v: Pose(v), None)
        turn = self.checked(keys, entry, "orientation", lambda v: Pose(orientation=v), Pose())
        frame = self.checked(keys, entry, "frame", lambda v: _name("frame", v), WORLD)
        holder = self.checked(keys, entry, "attached_to", lambda v: _name("attached_to", v), None)
        touch = self.checked(keys, entry, "touch_links", _links, NO_LINKS)
        if len(self.problems) > before or name is None or shape is None or at is None:
            return None
        return self.build(keys, lambda: SceneObject(name, shape, Pose(at.position, turn.orientation), frame, holder,
                                                    touch))

    def checked(self, keys: tuple[str | int, ...], entry: Mapping[Any, Any], key: str,
                 check: Callable[[Any], T], default: T) -> T:
        """The checked value of `key` of `entry`; `default` when absent, empty or invalid (the problem recorded)."""
        if entry.get(key) is None:
            return default
        checked = self.build((*keys, key), lambda: check(entry[key]))
        return default if checked is None else checked

    def shape(self, keys: tuple[str | int, ...], entry: Mapping[Any, Any]) -> Shape | None:
        """The one shape `entry` gives (box, sphere, cylinder or mesh)."""
        given = [key for key in SHAPE_KEYS if key in entry]
        if len(given) != 1:
            self.problem(keys, "an object needs exactly one shape", f"one of {', '.join(SHAPE_KEYS)}",
                         f"{'shapes ' + ', '.join(given) if given else 'no shape'} given", ENTRY_HOW)
            return None
        kind = given[0]
        value = entry[kind]
        where = (*keys, kind)
        if kind == "box":
            return self.build(where, lambda: Box(value))
        if kind == "sphere":
            return self.build(where, lambda: Sphere(value))
        if kind == "mesh" and isinstance(value, Mapping) and "vertices" in value:
            inline = self.parts(where, value, ("vertices", "triangles"))
            return None if inline is None else self.build(
                where, lambda: TriangleMesh(inline["vertices"], inline["triangles"]))
        parts = self.parts(where, value, ("radius", "length") if kind == "cylinder" else ("path",),
                           () if kind == "cylinder" else ("scale",))
        if parts is None:
            return None
        if kind == "cylinder":
            radius, length = parts["radius"], parts["length"]
            return self.build(where, lambda: Cylinder(radius, length))
        path, scale = parts["path"], parts.get("scale", ONES)
        mesh = self.build(where, lambda: Mesh(path, scale))
        return None if mesh is None else self.mesh_file((*where, "path"), mesh)

    def parts(self, keys: tuple[str | int, ...], value: object, required: tuple[str, ...],
              optional: tuple[str, ...] = ()) -> Mapping[Any, Any] | None:
        """`value` when it is a mapping of every key in `required` and maybe some in `optional`."""
        if (isinstance(value, Mapping) and all(key in value for key in required)
                and all(key in (*required, *optional) for key in value)):
            return value
        kind = str(keys[-1])
        self.problem(keys, f"{kind} is not a mapping of {' and '.join(required + optional)}",
                     f"{kind}: {{{', '.join(required + optional)}}}", f"{kind} is {_shown(value)}", ENTRY_HOW)
        return None

    def mesh_file(self, keys: tuple[str | int, ...], mesh: Mesh) -> Mesh | None:
        """`mesh` with a relative path made absolute against the base folder, when the file exists."""
        try:
            resolved = resolve_package_uri(mesh.path, base=self.base)
        except PlemError as error:
            self.problem(keys, f"mesh file not found: {mesh.path}", error.what, error.why,
                         "fix the mesh path, or add the folder of the package holding it to PLEM_PACKAGE_PATH")
            return None
        if mesh.path.startswith(("package://", "file://")):
            return mesh
        return dataclasses.replace(mesh, path=str(resolved.absolute()))
