"""The arm as the view draws it: its URDF with meshes found on plem's package path, the arm's joints mapped onto
the URDF's, and the links whose frames the view shows (base and tool)."""

from __future__ import annotations

import io
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import trimesh
import yourdfpy
from trimesh.visual import ColorVisuals, TextureVisuals
from trimesh.visual.material import PBRMaterial

from plem.core.paths import pinned_packages, resolve_package_uri
from plem.description.model import parse_urdf
from plem.errors import PlemError
from plem.planning.groups import end_link

URDF_SOURCE = Path("robot_description")
#: How rough the arm's surfaces are drawn (0 mirror, 1 chalk).
ROUGHNESS = 0.6


class ViewModel:
    """One arm's URDF for drawing; `missing` lists the mesh files that were not found (those links show less)."""

    def __init__(self, urdf_xml: str, joint_names: Sequence[str], packages: Mapping[str, str] | None = None) -> None:
        self.urdf_xml = urdf_xml
        self.joint_names = tuple(joint_names)
        self.packages = {name: Path(path) for name, path in (packages or {}).items()}
        model = parse_urdf(urdf_xml, URDF_SOURCE)
        unknown = [name for name in self.joint_names if name not in model.joints]
        if unknown:
            raise PlemError("the robot's joints are not those of its URDF", what="every joint of the arm in the URDF",
                            why=f"not in the URDF: {', '.join(unknown)}",
                            how="view the robot with the description it was launched with")
        roots = model.roots()
        self.base_link = roots[0] if roots else ""
        # the tool hangs below the arm's deepest joint (whatever order the arm lists its joints in)
        deepest = max(self.joint_names, key=lambda name: len(model.chain(self.base_link, model.joints[name].child or "")
                                                             or ()), default=None)
        self.tool_link = end_link(model, deepest) if deepest else self.base_link
        self.missing: list[str] = []
        self._resolved: dict[str, str] = {}
        probe = self.load()
        self._order = np.array([probe.actuated_joint_names.index(name) if name in probe.actuated_joint_names else -1
                                for name in self.joint_names])
        self._width = len(probe.actuated_joint_names)

    def _file(self, fname: str) -> str:
        """The file behind a mesh URI (package:// on plem's package path and the launched package); '' if none.
        yourdfpy passes the URI as `fname`."""
        uri = fname
        if uri not in self._resolved:
            try:
                with pinned_packages(self.packages):
                    self._resolved[uri] = str(resolve_package_uri(uri))
            except PlemError:
                self._resolved[uri] = ""
                self.missing.append(uri)
        return self._resolved[uri]

    def load(self) -> yourdfpy.URDF:
        """A fresh yourdfpy model with its visual meshes (each drawn arm needs its own)."""
        logging.getLogger("yourdfpy").setLevel(logging.ERROR)  # a missing mesh is reported through `missing`
        urdf = yourdfpy.URDF.load(io.StringIO(self.urdf_xml), filename_handler=self._file, build_scene_graph=True,
                                  load_meshes=True, build_collision_scene_graph=False, load_collision_meshes=False)
        for mesh in urdf.scene.geometry.values():
            matte(mesh)
        return urdf

    def configuration(self, positions: np.ndarray) -> np.ndarray:
        """The URDF's actuated joint values for the arm's positions (other joints at 0)."""
        values = np.zeros(self._width)
        known = self._order >= 0
        values[self._order[known]] = np.asarray(positions, dtype=float)[known]
        return values


def matte(mesh: trimesh.Trimesh) -> None:
    """Give `mesh` a non-metallic material in its own colour or texture: a mesh without one is drawn as bare metal
    (glTF's default), which shows only reflections and is black under the view's plain lights."""
    visual = mesh.visual
    if isinstance(visual, ColorVisuals):
        material = PBRMaterial(baseColorFactor=visual.main_color, metallicFactor=0.0,  # type: ignore[no-untyped-call]
                               roughnessFactor=ROUGHNESS)
        mesh.visual = TextureVisuals(material=material)  # type: ignore[no-untyped-call]  # trimesh is untyped
    elif isinstance(visual, TextureVisuals) and visual.material is not None:
        pbr = (visual.material if isinstance(visual.material, PBRMaterial)
               else visual.material.to_pbr())  # type: ignore[no-untyped-call]  # trimesh is untyped
        if pbr.metallicFactor is None:
            pbr.metallicFactor = 0.0
        visual.material = pbr
