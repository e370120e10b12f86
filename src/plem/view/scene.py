"""The 3D scene of the view: the measured arm, the commanded pose as a ghost, the base and tool frames, and
when a planner runs, its planning scene's objects and the newest planned path."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh
import viser
from viser.extras import ViserUrdf

from plem.view.model import ViewModel

#: The commanded pose: a translucent blue arm over the measured one.
GHOST_COLOR = (0.25, 0.55, 1.0, 0.35)
OBJECT_COLOR = (0.85, 0.45, 0.2)
PATH_COLOR = (0.1, 0.7, 0.3)
#: How close (rad, every joint) the arm must be to a plan's start or end to count as there.
PLAN_REACHED_RAD = 1e-3
AXES_LENGTH, AXES_RADIUS = 0.12, 0.004
#: Positions closer than this (rad) to the ones drawn are not sent again.
UNCHANGED_RAD = 1e-5


def _wxyz(xyzw: Sequence[float]) -> tuple[float, float, float, float]:
    x, y, z, w = xyzw
    return (w, x, y, z)


def matrix_pose(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(wxyz, position) of a 4×4 transform."""
    return viser.transforms.SO3.from_matrix(matrix[:3, :3]).wxyz, matrix[:3, 3].copy()


@dataclass
class PlanShown:
    """The plan drawn: where it starts and ends (rad), its duration, its label and what the label says of it."""

    start: np.ndarray
    end: np.ndarray
    duration_s: float
    label: Any
    state: str = ""

    def show(self, state: str) -> None:
        """Put `state` on the label beside the duration."""
        self.state = state
        self.label.text = f"plan {self.duration_s:.2f} s — {state}"


class ArmScene:
    """What the 3D view draws of one arm."""

    def __init__(self, server: viser.ViserServer, model: ViewModel, prefix: str = "") -> None:
        self.server = server
        self.model = model
        self.measured = ViserUrdf(server, model.load(), root_node_name="/arm")
        self.commanded = ViserUrdf(server, model.load(), root_node_name="/commanded",
                                   mesh_color_override=GHOST_COLOR)
        self._kinematics = model.load()
        self._prefix = prefix
        scene = server.scene
        scene.add_grid("/grid", width=2.0, height=2.0, cell_size=0.1, plane="xy")
        self.base_frame = scene.add_frame("/frames/base", axes_length=AXES_LENGTH, axes_radius=AXES_RADIUS)
        scene.add_label("/frames/base/name", model.base_link, position=(0.0, 0.0, -0.03))
        self.tool_frame = scene.add_frame("/frames/tool", axes_length=AXES_LENGTH, axes_radius=AXES_RADIUS)
        scene.add_label("/frames/tool/name", model.tool_link, position=(0.0, 0.0, 0.03))
        server.initial_camera.position = (1.3, -1.3, 1.1)
        server.initial_camera.look_at = (0.0, 0.0, 0.45)
        self._drawn: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
        self._objects: dict[str, Any] = {}
        self._path: list[Any] = []
        self._plan: PlanShown | None = None

    def show(self, position: np.ndarray, command_position: np.ndarray | None) -> bool:
        """Move the drawn arms to these positions; False when nothing changed enough to send."""
        measured, commanded = self._drawn
        changed = False
        if measured is None or np.max(np.abs(measured - position)) > UNCHANGED_RAD:
            self.measured.update_cfg(self.model.configuration(position))
            self.tool_frame.wxyz, self.tool_frame.position = matrix_pose(self.link_transform(position,
                                                                                              self.model.tool_link))
            measured, changed = position.copy(), True
        if command_position is None:
            self.commanded.show_visual = False
        elif commanded is None or np.max(np.abs(commanded - command_position)) > UNCHANGED_RAD:
            self.commanded.update_cfg(self.model.configuration(command_position))
            self.commanded.show_visual = True
            commanded, changed = command_position.copy(), True
        self._drawn = (measured, commanded)
        return changed

    def link_transform(self, position: np.ndarray, link: str) -> np.ndarray:
        """The 4×4 pose of `link` in the base frame with the arm at `position`."""
        self._kinematics.update_cfg(self.model.configuration(position))
        return np.asarray(self._kinematics.get_transform(link, self.model.base_link))

    def _link(self, frame: str) -> str:
        """The URDF link a scene frame names (the /tf prefix dropped); the base for the world frame."""
        name = frame.removeprefix(self._prefix)
        return name if name in self._kinematics.link_map else self.model.base_link

    def show_path(self, points: Sequence[Sequence[float]], duration_s: float) -> None:
        """The tool's path along a plan's points, labelled with its duration and, until the arm moves along it,
        "not executed" (a dry run, or a plan not sent yet)."""
        for handle in self._path:
            handle.remove()
        self._path, self._plan = [], None
        if len(points) < 2:
            return
        tool = np.array([self.link_transform(np.asarray(p), self.model.tool_link)[:3, 3] for p in points])
        scene = self.server.scene
        label = scene.add_label("/plan/end", "", position=tuple(tool[-1]))
        self._path = [scene.add_spline_catmull_rom("/plan/path", tool, thickness=4.0, thickness_units="screen",
                                                   color=PATH_COLOR), label]
        self._plan = PlanShown(np.asarray(points[0], float), np.asarray(points[-1], float), duration_s, label)
        self._plan.show("dry run — not executed")

    def follow_plan(self, position: np.ndarray) -> None:
        """Say on the plan's label whether the arm ran it: still at its start, on its way, or at its end."""
        plan = self._plan
        if plan is None or plan.state == "executed":
            return
        if np.max(np.abs(position - plan.end)) <= PLAN_REACHED_RAD:
            plan.show("executed")
        elif np.max(np.abs(position - plan.start)) > PLAN_REACHED_RAD:
            plan.show("executing")

    def show_objects(self, objects: Sequence[dict[str, Any]], arm_position: np.ndarray) -> None:
        """The planning scene's objects (boxes, spheres, cylinders, meshes), attached ones on their links."""
        for handle in self._objects.values():
            handle.remove()
        self._objects = {}
        for entry in objects:
            placement = np.eye(4)
            frame = str(entry.get("attached_to") or entry.get("frame") or "")
            if frame:
                placement = self.link_transform(arm_position, self._link(frame))
            local = np.eye(4)
            local[:3, :3] = viser.transforms.SO3(np.array(_wxyz(entry["orientation"]))).as_matrix()
            local[:3, 3] = entry["position"]
            wxyz, position = matrix_pose(placement @ local)
            name = f"/scene/{len(self._objects)}"
            self._objects[entry["name"]] = self._shape(name, entry, wxyz, position)

    def _shape(self, name: str, entry: dict[str, Any], wxyz: np.ndarray, position: np.ndarray) -> Any:
        scene = self.server.scene
        if "box" in entry:
            return scene.add_box(name, color=OBJECT_COLOR, dimensions=tuple(entry["box"]), wxyz=wxyz,
                                 position=position)
        if "sphere" in entry:
            return scene.add_icosphere(name, radius=float(entry["sphere"]), color=OBJECT_COLOR, wxyz=wxyz,
                                       position=position)
        if "cylinder" in entry:
            cylinder = entry["cylinder"]
            return scene.add_cylinder(name, radius=float(cylinder["radius"]), height=float(cylinder["length"]),
                                      color=OBJECT_COLOR, wxyz=wxyz, position=position)
        mesh = entry["mesh"]
        if "vertices" in mesh:
            vertices, faces = np.array(mesh["vertices"], dtype=float), np.array(mesh["triangles"])
        else:
            loaded: Any = trimesh.load(mesh["path"], force="mesh")
            vertices = np.asarray(loaded.vertices) * np.asarray(mesh.get("scale", 1.0))
            faces = np.asarray(loaded.faces)
        return scene.add_mesh_simple(name, vertices, faces, color=OBJECT_COLOR, wxyz=wxyz, position=position)
