"""The planning scene: shapes and poses checked, changes counted, JSON round trips, scene files read with every
problem at its line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from plem.errors import PlemError
from plem.planning.poses import Pose
from plem.planning.scene import (
    WORLD,
    Box,
    Cylinder,
    Mesh,
    PlanningScene,
    SceneError,
    SceneErrors,
    SceneObject,
    Sphere,
    read_scene_file,
)

TABLE = SceneObject("table", Box((1.2, 0.8, 0.05)), Pose((0.5, 0.0, -0.03)))


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("make", [
    lambda: Box((1.0, 0.0, 1.0)), lambda: Box((1.0, math.inf, 1.0)), lambda: Box((1.0, 1.0)),  # type: ignore[arg-type]
    lambda: Sphere(-0.1), lambda: Sphere(True), lambda: Cylinder(0.1, math.nan), lambda: Mesh("a.stl", (1, 0, 1)),
    lambda: Mesh(""), lambda: SceneObject("", Sphere(1.0)), lambda: SceneObject("a\nb", Sphere(1.0)),
    lambda: SceneObject("x" * 257, Sphere(1.0)),
    lambda: SceneObject("a", Sphere(1.0), attached_to="tcp", touch_links=("",)),
    lambda: SceneObject("a", Sphere(1.0), frame="link3", attached_to="tcp"),
    lambda: SceneObject("a", Sphere(1.0), touch_links=("link6",)),
])
def test_invalid_values_are_scene_errors_naming_the_fix(make):
    with pytest.raises(SceneError) as error:
        make()
    assert isinstance(error.value, PlemError) and error.value.how


def test_an_attached_object_gives_its_pose_in_its_link():
    held = SceneObject("tool", Cylinder(0.02, 0.2), attached_to="tcp", touch_links=("link6", "link6"))
    assert held.frame == "tcp" and held.touch_links == ("link6",)
    assert held.allowed_links() == {"tcp", "link6"} and TABLE.allowed_links() == frozenset()


def test_every_change_counts_and_names_are_replaced_as_moveit_adds():
    scene = PlanningScene()
    scene.add(TABLE)
    scene.add(SceneObject("table", Box((1.0, 1.0, 0.02)), Pose((0.4, 0.0, -0.01))))
    assert scene.get("table").shape == Box((1.0, 1.0, 0.02))
    scene.add(SceneObject("ball", Sphere(0.05), Pose((0.3, 0.2, 0.1))))
    scene.move("ball", Pose((0.3, 0.2, 0.2)))
    scene.attach("ball", "tcp", Pose((0.0, 0.0, 0.05)), ["link6"])
    held = scene.get("ball")
    assert (held.attached_to, held.frame, held.touch_links, held.pose.position) == ("tcp", "tcp", ("link6",),
                                                                                    (0.0, 0.0, 0.05))
    scene.detach("ball", Pose((0.1, 0.1, 0.1)))
    placed = scene.get("ball")
    assert (placed.attached_to, placed.frame, placed.touch_links) == (None, WORLD, ())
    scene.remove("table")
    assert [obj.name for obj in scene.objects()] == ["ball"] and scene.version == 7


@pytest.mark.parametrize("change", [
    lambda scene: scene.remove("chair"), lambda scene: scene.move("chair", Pose()),
    lambda scene: scene.detach("chair", Pose()), lambda scene: scene.attach("chair", "tcp", Pose()),
])
def test_unknown_names_list_the_known_ones(change):
    scene = PlanningScene([TABLE, SceneObject("ball", Sphere(0.1), Pose((1.0, 0.0, 0.0)))])
    with pytest.raises(SceneError) as error:
        change(scene)
    assert error.value.why == "known objects: table, ball" and scene.version == 0


def test_detaching_a_world_object_is_refused():
    with pytest.raises(SceneError, match="not attached"):
        PlanningScene([TABLE]).detach("table", Pose())


def test_json_round_trips_through_text(tmp_path: Path):
    mesh = tmp_path / "part.stl"
    mesh.write_text("solid part\nendsolid part\n")
    scene = PlanningScene([TABLE, SceneObject("can", Cylinder(0.05, 0.3), Pose((0.4, -0.2, 0.15), (0, 0, 1, 1))),
                           SceneObject("part", Mesh(str(mesh), (0.001, 0.001, 0.001)), Pose((0.3, 0.3, 0.0))),
                           SceneObject("tool", Sphere(0.03), Pose((0, 0, 0.05)), attached_to="tcp",
                                       touch_links=("link6",))])
    scene.move("can", Pose((0.4, -0.2, 0.16)))
    again = PlanningScene.from_json(json.loads(json.dumps(scene.to_json())))
    assert again.objects() == scene.objects() and again.version == scene.version == 1
    assert again.to_json() == scene.to_json()


def test_json_problems_name_where_they_are():
    with pytest.raises(SceneErrors) as error:
        PlanningScene.from_json({"version": -1, "objects": [{"name": "a", "box": [1, 2, True], "position": [0, 0, 0]},
                                                            {"name": "b", "sphere": 0.1}, "c"]})
    assert [problem.why.split(":")[0] for problem in error.value.errors] == [
        "version", "objects[0].box", "objects[1]", "objects[2]"]
    assert isinstance(error.value, SceneError)
    with pytest.raises(SceneError):
        PlanningScene.from_json([1, 2])


def test_a_scene_file_gives_its_objects(tmp_path: Path):
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "part.stl").write_text("solid part\nendsolid part\n")
    path = write(tmp_path, """\
objects:
  - name: table
    box: [1.2, 0.8, 0.05]
    position: [0.5, 0.0, -0.03]
  - {name: ball, sphere: 0.1, position: [0.4, 0, 0.3], orientation: [0, 0, 0, 2], frame: link0}
  - name: can
    cylinder: {radius: 0.05, length: 0.3}
    position: [0, 0, 0.1]
    attached_to: tcp
    touch_links: [link6]
  - {name: part, mesh: {path: meshes/part.stl}, position: [0, 0, 0]}
""")
    table, ball, can, part = read_scene_file(path)
    assert table == TABLE
    assert (ball.shape, ball.frame, ball.pose.orientation) == (Sphere(0.1), "link0", (0, 0, 0, 1))
    assert (can.shape, can.attached_to, can.frame, can.touch_links) == (Cylinder(0.05, 0.3), "tcp", "tcp", ("link6",))
    assert part.shape == Mesh(str(tmp_path / "meshes" / "part.stl"))


def test_scene_file_problems_are_listed_together_with_their_lines(tmp_path: Path):
    path = write(tmp_path, """\
objects:
  - name: table
    box: [1.2, 0.8, 0.05]
    position: [0.5, 0.0, -0.03]
  - name: ball
    sphere: -0.1
    position: [0.5, 0.0]
  - name: can
    cylinder: {radius: 0.05}
    position: [0.5, 0.0, 0.3]
    orientation: [0, 0, 0, 0]
  - name: part
    mesh: {path: nowhere.stl}
    position: [0, 0, 0]
  - 7
  - name: table
    box: [1, 1, 1]
    position: [0, 0, 0]
    colour: red
  - {name: rod, box: [1, 1, 1], sphere: 1, position: [0, 0, 0]}
""")
    with pytest.raises(SceneErrors) as error:
        read_scene_file(path)
    whys = [problem.why for problem in error.value.errors]
    assert [why.split(": ")[0] for why in whys] == [f"{path}:{line}" for line in (6, 7, 9, 11, 13, 15, 19, 16, 20)]
    assert "sphere radius is -0.1" in whys[0] and "unknown: colour" in whys[6] and "are both table" in whys[7]
    assert "nowhere.stl" in whys[4] and all(problem.how for problem in error.value.errors)
    assert str(path) in error.value.summary


@pytest.mark.parametrize(("text", "found"), [
    ("objects: [\n", "not valid YAML"), ("- 1\n", "lists no objects"), ("things: []\n", "no objects: key"),
    ("objects: {a: 1}\n", "objects is not a list"),
])
def test_a_scene_file_of_the_wrong_shape_is_one_scene_error(tmp_path: Path, text: str, found: str):
    with pytest.raises(SceneError) as error:
        read_scene_file(write(tmp_path, text))
    assert found in str(error.value)


def test_an_empty_object_list_is_an_empty_scene(tmp_path: Path):
    assert read_scene_file(write(tmp_path, "objects:\n")) == []


def test_a_missing_scene_file_is_a_scene_error(tmp_path: Path):
    with pytest.raises(SceneError, match="cannot read the scene file"):
        read_scene_file(tmp_path / "none.yaml")
