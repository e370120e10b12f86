"""Collision checking on real arms: the built-in Indys (primitives), UR5 and Panda (meshes), with scene objects."""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from plem.description.model import parse_srdf
from plem.description.problems import DescriptionError
from plem.description.validate import validate_package
from plem.planning.collision import CollisionChecker
from plem.planning.poses import Pose
from plem.planning.scene import Box, Cylinder, Mesh, PlanningScene, SceneError, SceneErrors, SceneObject, Sphere

TABLE = SceneObject("table", Box((1.2, 0.8, 0.05)), Pose((0.5, 0.0, -0.03)))
INDY7 = "indy7_v2_description"
DATA = "share/example-robot-data/robots"
PANDA_MESH = "package://example-robot-data/robots/panda_description/meshes/collision/hand.stl"


class Arm:
    """A checker and the facts the tests need about its arm."""

    def __init__(self, package: str) -> None:
        report = validate_package(package)
        assert report.srdf is not None and report.urdf_xml is not None
        self.urdf = report.urdf_xml
        self.model = pin.buildModelFromXML(self.urdf)
        self.disabled = [(a, b) for a, b, _ in report.srdf.disabled_collisions]
        self.checker = CollisionChecker(self.model, self.urdf, self.disabled)
        self.home = np.array(report.srdf.poses([self.model.names[j] for j in range(1, self.model.njoints)])["home"])

    def frame(self, q: np.ndarray, link: str) -> pin.SE3:
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, q)
        return data.oMf[self.model.getFrameId(link)]


@pytest.fixture(scope="module")
def indy7() -> Arm:
    return Arm(INDY7)


def folded(arm: Arm) -> np.ndarray:
    """The elbow (joint2 of the Indy7, joint3 of the RP2) folding the forearm back onto the upper arm."""
    q = np.zeros(arm.model.nq)
    q[2 if arm.model.nq == 6 else 3] = 3.0
    return q


@pytest.mark.parametrize("package", [INDY7, "indyrp2_v2_description"])
def test_builtin_arms_are_free_at_home_and_collide_folded(package: str):
    arm = Arm(package)
    assert arm.checker.is_free(arm.home) and arm.checker.contacts(arm.home) == []
    q = folded(arm)
    contacts = arm.checker.contacts(q)
    assert not arm.checker.is_free(q) and ("link2", "link4") in contacts
    assert {link for pair in contacts for link in pair} <= set(arm.checker.link_names())


def test_links_are_the_urdf_links(indy7: Arm):
    assert indy7.checker.link_names() == ("link0", "link1", "link2", "link3", "link4", "link5", "link6", "tcp")


def test_a_disabled_pair_is_not_reported(indy7: Arm):
    q = folded(indy7)
    assert indy7.checker.contacts(q) == [("link1", "link5"), ("link2", "link4"), ("link2", "link5")]
    checker = CollisionChecker(indy7.model, indy7.urdf, [*indy7.disabled, ("link4", "link2")])
    assert checker.contacts(q) == [("link1", "link5"), ("link2", "link5")]


def test_links_joined_by_a_joint_are_never_checked(indy7: Arm):
    """Every pair of neighbouring links overlaps at the joint between them; no SRDF is needed to say so."""
    every = pin.buildGeomFromUrdfString(indy7.model, indy7.urdf, pin.COLLISION)
    every.addAllCollisionPairs()
    data = pin.GeometryData(every)
    pin.computeCollisions(indy7.model, indy7.model.createData(), every, data, indy7.home, False)
    link = [indy7.model.frames[shape.parentFrame].name for shape in every.geometryObjects]
    overlapping = {(link[pair.first], link[pair.second])
                   for pair, result in zip(every.collisionPairs, data.collisionResults, strict=True)
                   if result.isCollision()}
    assert overlapping == {(f"link{i}", f"link{i + 1}") for i in range(6)}
    assert CollisionChecker(indy7.model, indy7.urdf, []).contacts(indy7.home) == []


def test_a_box_at_the_tool_collides_and_is_named(indy7: Arm):
    tool = indy7.frame(indy7.home, "tcp").translation
    scene = PlanningScene([TABLE, SceneObject("crate", Box((0.04, 0.04, 0.04)), Pose(tuple(tool)))])
    indy7.checker.set_scene(scene)
    try:
        assert not indy7.checker.is_free(indy7.home)
        assert indy7.checker.contacts(indy7.home) == [("link6", "crate")]
        scene.move("crate", Pose((tool[0], tool[1], tool[2] - 0.3)))
        indy7.checker.set_scene(scene)
        assert indy7.checker.is_free(indy7.home)
    finally:
        indy7.checker.set_scene(PlanningScene())


def test_world_objects_do_not_collide_with_each_other(indy7: Arm):
    indy7.checker.set_scene(PlanningScene([TABLE, SceneObject("box", Box((0.2, 0.2, 0.2)), Pose((0.5, 0.0, 0.0)))]))
    try:
        assert indy7.checker.is_free(indy7.home)
    finally:
        indy7.checker.set_scene(PlanningScene())


def test_an_attached_object_moves_with_its_link_and_may_touch_its_touch_links(indy7: Arm):
    """A 1 m rod held 2 cm deep in the tool points down into the table at home, and up, clear of all, at zero."""
    rod = SceneObject("rod", Cylinder(0.02, 1.0), Pose((0.0, 0.0, 0.48)), attached_to="tcp", touch_links=("link6",))
    scene = PlanningScene([TABLE, rod])
    checker = indy7.checker
    checker.set_scene(scene)
    try:
        assert checker.contacts(indy7.home) == [("table", "rod")]
        assert checker.is_free(np.zeros(6))
        scene.attach("rod", "tcp", rod.pose)  # the rod passes through link6 without it among its touch links
        checker.set_scene(scene)
        assert checker.contacts(np.zeros(6)) == [("link6", "rod")]
        scene.detach("rod", Pose(tuple(indy7.frame(indy7.home, "tcp").act(np.array([0.0, 0.0, 0.48])))))
        checker.set_scene(scene)
        assert checker.contacts(indy7.home) == [("link6", "rod")]  # left where the tool held it, 2 cm deep
        assert checker.is_free(np.zeros(6))  # and a world object now: the table beneath it is no contact
    finally:
        checker.set_scene(PlanningScene())


def test_objects_attached_to_other_bodies_collide_with_each_other(indy7: Arm):
    scene = PlanningScene([SceneObject("cap", Sphere(0.3), attached_to="tcp"),
                           SceneObject("sleeve", Sphere(0.3), attached_to="link4", touch_links=["link3", "link5"])])
    checker = CollisionChecker(indy7.model, indy7.urdf, indy7.disabled)
    checker.set_scene(scene)
    pairs = checker.contacts(np.zeros(6))
    assert ("cap", "sleeve") in pairs and ("link6", "cap") in pairs and ("link4", "sleeve") not in pairs


@pytest.mark.parametrize(("obj", "found"), [
    (SceneObject("a", Sphere(0.1), attached_to="gripper"), "unknown link gripper"),
    (SceneObject("a", Sphere(0.1), attached_to="tcp", touch_links=("finger",)), "unknown link finger"),
    (SceneObject("a", Sphere(0.1), frame="link3"), "link3, which moves"),
    (SceneObject("link2", Sphere(0.1)), "name of a link"),
    (SceneObject("a", Mesh("/nowhere/part.stl")), "cannot be read"),
])
def test_scene_problems_are_scene_errors_and_keep_the_old_scene(indy7: Arm, obj: SceneObject, found: str):
    checker = CollisionChecker(indy7.model, indy7.urdf, indy7.disabled)
    tool = indy7.frame(indy7.home, "tcp").translation
    checker.set_scene(PlanningScene([SceneObject("crate", Box((0.04, 0.04, 0.04)), Pose(tuple(tool)))]))
    with pytest.raises(SceneError, match=found) as error:
        checker.set_scene(PlanningScene([obj]))
    assert error.value.how
    assert checker.contacts(indy7.home) == [("link6", "crate")]


def test_all_scene_problems_are_reported_together(indy7: Arm):
    scene = PlanningScene([SceneObject("a", Sphere(0.1), attached_to="gripper"), SceneObject("link2", Sphere(0.1))])
    with pytest.raises(SceneErrors) as error:
        indy7.checker.set_scene(scene)
    assert len(error.value.errors) == 2


def test_a_world_object_may_be_placed_in_a_link_fixed_to_the_world(indy7: Arm):
    checker = CollisionChecker(indy7.model, indy7.urdf, indy7.disabled)
    checker.set_scene(PlanningScene([SceneObject("post", Box((0.05, 0.05, 0.05)), Pose((0.0, 0.0, 0.3)),
                                                 frame="link0")]))
    assert checker.contacts(np.zeros(6)) == [("link1", "post")]


def test_is_free_agrees_with_contacts_on_random_configurations(indy7: Arm):
    checker = CollisionChecker(indy7.model, indy7.urdf, indy7.disabled)
    checker.set_scene(PlanningScene([TABLE]))
    rng = np.random.default_rng(7)
    configurations = rng.uniform(indy7.model.lowerPositionLimit, indy7.model.upperPositionLimit, (300, 6))
    free = [checker.is_free(q) for q in configurations]
    assert free == [not checker.contacts(q) for q in configurations]
    assert 0 < sum(free) < len(free)


def test_the_srdf_may_not_disable_links_the_urdf_lacks(indy7: Arm):
    with pytest.raises(DescriptionError, match="gripper"):
        CollisionChecker(indy7.model, indy7.urdf, [("link6", "gripper")])


@pytest.fixture
def data_prefix(monkeypatch: pytest.MonkeyPatch) -> Path:
    """example-robot-data's install prefix on AMENT_PREFIX_PATH, so its package:// URIs resolve."""
    prefix = Path(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix"))
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    return prefix


def test_ur5_meshes_load_and_its_home_is_free(data_prefix: Path):
    urdf = (data_prefix / DATA / "ur_description/urdf/ur5_robot.urdf").read_text()
    srdf = parse_srdf((data_prefix / DATA / "ur_description/srdf/ur5.srdf").read_text(), Path("ur5.srdf"))
    model = pin.buildModelFromXML(urdf)
    checker = CollisionChecker(model, urdf, [(a, b) for a, b, _ in srdf.disabled_collisions])
    assert checker.is_free(pin.neutral(model))
    q = pin.neutral(model)
    q[2] = 3.0  # the elbow folds the forearm back onto the upper arm
    assert ("upper_arm_link", "wrist_2_link") in checker.contacts(q) and not checker.is_free(q)


def test_panda_meshes_load_with_its_fingers_locked_and_its_home_is_free(data_prefix: Path):
    urdf = (data_prefix / DATA / "panda_description/urdf/panda.urdf").read_text()
    srdf = parse_srdf((data_prefix / DATA / "panda_description/srdf/panda.srdf").read_text(), Path("panda.srdf"))
    full = pin.buildModelFromXML(urdf)
    fingers = [full.getJointId(name) for name in ("panda_finger_joint1", "panda_finger_joint2")]
    model = pin.buildReducedModel(full, fingers, pin.neutral(full))
    checker = CollisionChecker(model, urdf, [(a, b) for a, b, _ in srdf.disabled_collisions])
    home = np.array(srdf.poses([model.names[j] for j in range(1, model.njoints)])["default"])
    assert model.nq == 7 and checker.is_free(home) and checker.contacts(home) == []
    data = model.createData()
    pin.framesForwardKinematics(model, data, home)
    hand = pin.SE3ToXYZQUAT(data.oMf[model.getFrameId("panda_hand")])
    copy = SceneObject("hand_copy", Mesh(PANDA_MESH), Pose(tuple(hand[:3]), tuple(hand[3:])))
    checker.set_scene(PlanningScene([copy]))
    assert ("panda_hand", "hand_copy") in checker.contacts(home) and not checker.is_free(home)
    assert checker.is_free(np.zeros(7))


def test_a_urdf_whose_meshes_are_missing_names_mesh_and_link(data_prefix: Path, monkeypatch: pytest.MonkeyPatch):
    urdf = (data_prefix / DATA / "ur_description/urdf/ur5_robot.urdf").read_text()
    monkeypatch.delenv("AMENT_PREFIX_PATH")
    with pytest.raises(DescriptionError) as error:
        CollisionChecker(pin.buildModelFromXML(urdf), urdf, [])
    assert re.search(r"link shoulder_link: mesh package://example-robot-data/\S+/shoulder.stl", error.value.why)
    assert "PLEM_PACKAGE_PATH" in error.value.how
