"""A description package given by path (`plem launch ./my_arm`, `plem validate ./my_arm`) that names its own
collision meshes as `package://`: the planner finds them in that package, without PLEM_PACKAGE_PATH, for the
robot's geometry and for scene objects alike."""

from __future__ import annotations

from pathlib import Path

import pytest
import trimesh

from plem.control.limits import ArmLimits
from plem.description.validate import validate_package
from plem.planning.planner import Planner
from plem.planning.poses import Pose
from plem.planning.scene import Box, Mesh, SceneObject
from tests.integration.packages import copy_builtin

NAME = "my_arm_description"
BLOCK = f"package://{NAME}/meshes/block.stl"
#: Where the package's block stands, beside the arm's base and clear of the arm at home.
BLOCK_AT = (-0.6, 0.0, 0.05)
FIXTURE = f"""
  <link name="fixture">
    <collision><geometry><mesh filename="{BLOCK}"/></geometry></collision>
  </link>
  <joint name="fixture_joint" type="fixed">
    <parent link="link0"/><child link="fixture"/><origin xyz="{' '.join(map(str, BLOCK_AT))}" rpy="0 0 0"/>
  </joint>
</robot>"""


def package_with_a_mesh(directory: Path) -> Path:
    """The built-in Indy7 as package `my_arm_description` (given by path) with a fixed link whose collision is a
    10 cm cube mesh of its own, named by package:// URI."""
    copy = copy_builtin("indy7_v2", directory / "copy")
    root = directory / NAME
    copy.rename(root)
    for path in root.rglob("*"):
        if path.is_file() and path.suffix in (".xml", ".xacro", ".txt", ".srdf"):
            path.write_text(path.read_text().replace("indy7_v2_description", NAME))
    (root / "meshes").mkdir()
    trimesh.creation.box((0.1, 0.1, 0.1)).export(root / "meshes" / "block.stl")
    xacro = root / "urdf" / "indy7_v2.urdf.xacro"
    xacro.write_text(xacro.read_text().replace("</robot>", FIXTURE))
    return root


def test_meshes_of_a_package_given_by_path_are_found(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("PLEM_PACKAGE_PATH", "AMENT_PREFIX_PATH"):
        monkeypatch.delenv(name, raising=False)
    report = validate_package(package_with_a_mesh(tmp_path))
    assert report.urdf is not None
    joint_names = tuple(joint.name for joint in report.urdf.actuated_joints)
    planner = Planner.for_package(report, joint_names, ArmLimits.from_joint_limits(report.limits, joint_names), 0.001)
    home = planner.named_states["home"].tolist()
    assert planner.contacts(home) == []
    # a solid box around the cube: a mesh is its surface, so a box inside it would touch nothing
    planner.scene.add(SceneObject("probe", Box((0.15, 0.15, 0.15)), Pose(BLOCK_AT)))
    assert sorted(planner.contacts(home)[0]) == ["fixture", "probe"]       # the robot's mesh was loaded
    planner.scene.remove("probe")
    planner.scene.add(SceneObject("crate", Mesh(BLOCK), Pose((0.0, 0.0, 0.1))))      # in the arm's base
    assert any("crate" in pair for pair in planner.contacts(home))                     # and the scene's
