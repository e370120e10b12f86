"""robot_state_publisher's /tf and /tf_static transforms, checked against pinocchio and hand-computed poses."""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pinocchio as pin
import pytest

from plem.description.validate import validate_package
from plem.errors import ConfigError
from plem.middleware.transforms import Transform, TreeTransforms, tf_message
from plem.middleware.types import library

PREFIX = "arm_left/"


@pytest.fixture(scope="module")
def indy7() -> tuple[str, dict[str, tuple[str, str, str]]]:
    """The rendered Indy7 URDF and, per joint, its (type, parent, child) as plem's validator read them."""
    report = validate_package("indy7_description")
    assert report.urdf_xml is not None and report.urdf is not None
    joints = {name: (joint.type, joint.parent or "", joint.child or "") for name, joint in report.urdf.joints.items()}
    return report.urdf_xml, joints


def matrix(transform: Transform) -> np.ndarray:
    """4×4 homogeneous matrix of a transform, from its quaternion by the textbook formula."""
    x, y, z, w = transform.rotation
    out = np.eye(4)
    out[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                   [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                   [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    out[:3, 3] = transform.translation
    return out


def link_poses(transforms: Iterable[Transform]) -> dict[str, np.ndarray]:
    """Every frame's pose in the root frame, chaining parent → child transforms from the one root."""
    pending = list(transforms)
    children = {t.child for t in pending}
    roots = {t.parent for t in pending} - children
    assert len(roots) == 1
    poses = {roots.pop(): np.eye(4)}
    while pending:
        ready = [t for t in pending if t.parent in poses]
        assert ready, "transforms do not form a tree"
        for t in ready:
            poses[t.child] = poses[t.parent] @ matrix(t)
        pending = [t for t in pending if t.child not in poses]
    return poses


def rx(a: float) -> np.ndarray:
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def ry(a: float) -> np.ndarray:
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def rz(a: float) -> np.ndarray:
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return rz(yaw) @ ry(pitch) @ rx(roll)


def about(axis: Iterable[float], angle: float) -> np.ndarray:
    """Rotation by `angle` about `axis` (Rodrigues' formula)."""
    k = np.asarray(list(axis), dtype=float)
    k /= np.linalg.norm(k)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


def test_indy7_matches_pinocchio_for_every_link(indy7: tuple[str, dict[str, tuple[str, str, str]]]) -> None:
    urdf, _ = indy7
    tree = TreeTransforms(urdf, "")
    model = pin.buildModelFromXML(urdf)
    data = model.createData()
    rng = np.random.default_rng(7)
    links = [frame.name for frame in model.frames if frame.type == pin.FrameType.BODY]
    assert {"link0", "link6", "tcp"} <= set(links)
    for _ in range(8):
        positions = {name: float(rng.uniform(-math.pi, math.pi)) for name in tree.moving_joints}
        q = pin.neutral(model)
        for index in range(1, model.njoints):
            joint, value = model.joints[index], positions[model.names[index]]
            if joint.nq == 1:
                q[joint.idx_q] = value
            else:                                   # continuous joints: (cos, sin)
                q[joint.idx_q:joint.idx_q + 2] = math.cos(value), math.sin(value)
        pin.framesForwardKinematics(model, data, q)
        poses = link_poses([*tree.static(), *tree.moving(positions)])
        assert set(links) <= set(poses)
        for link in links:
            expected = data.oMf[model.getFrameId(link)]
            np.testing.assert_allclose(poses[link][:3, 3], expected.translation, rtol=0, atol=1e-9, err_msg=link)
            np.testing.assert_allclose(poses[link][:3, :3], expected.rotation, rtol=0, atol=1e-9, err_msg=link)


def test_static_holds_the_fixed_joints_and_moving_the_others(
        indy7: tuple[str, dict[str, tuple[str, str, str]]]) -> None:
    urdf, joints = indy7
    tree = TreeTransforms(urdf, PREFIX)
    fixed = {(PREFIX + parent, PREFIX + child) for kind, parent, child in joints.values() if kind == "fixed"}
    others = {(PREFIX + parent, PREFIX + child) for kind, parent, child in joints.values() if kind != "fixed"}
    assert fixed and others
    assert {(t.parent, t.child) for t in tree.static()} == fixed
    assert len(tree.static()) == len(fixed)
    assert set(tree.moving_joints) == {name for name, (kind, _, _) in joints.items() if kind != "fixed"}
    moved = tree.moving(dict.fromkeys(tree.moving_joints, 0.3))
    assert {(t.parent, t.child) for t in moved} == others
    assert len(moved) == len(others)


def test_frame_prefix_is_prepended_to_parent_and_child(indy7: tuple[str, dict[str, tuple[str, str, str]]]) -> None:
    urdf, _ = indy7
    plain, prefixed = TreeTransforms(urdf, ""), TreeTransforms(urdf, PREFIX)
    positions = {name: 0.1 * i for i, name in enumerate(plain.moving_joints)}
    for bare, named in [*zip(plain.static(), prefixed.static(), strict=True),
                        *zip(plain.moving(positions), prefixed.moving(positions), strict=True)]:
        assert named.parent == PREFIX + bare.parent and named.child == PREFIX + bare.child
        assert (named.translation, named.rotation) == (bare.translation, bare.rotation)
    assert any(t.parent == "arm_left/link0" for t in prefixed.moving(positions))


TOY = """<?xml version="1.0"?>
<robot name="toy">
  <link name="base"/><link name="slider"/><link name="arm"/><link name="finger"/><link name="sensor"/>
  <link name="spare"/><link name="plate"/><link name="loose"/>
  <joint name="lift" type="prismatic">
    <parent link="base"/><child link="slider"/>
    <origin xyz="0.1 0 0.2" rpy="0 0 1.5707963267948966"/><axis xyz="0 0 2"/>
  </joint>
  <joint name="turn" type="continuous">
    <parent link="slider"/><child link="arm"/>
    <origin xyz="0.3 0 0" rpy="0.2 -0.4 0.7"/><axis xyz="1 1 0"/>
  </joint>
  <joint name="finger_joint" type="revolute">
    <parent link="arm"/><child link="finger"/>
    <origin xyz="0 0.05 0"/><axis xyz="0 1 0"/>
    <mimic joint="turn" multiplier="2" offset="0.1"/>
  </joint>
  <joint name="sensor_mount" type="fixed">
    <parent link="arm"/><child link="sensor"/><origin xyz="0.01 0.02 0.03" rpy="0.3 0.2 0.1"/>
  </joint>
  <joint name="spare_joint" type="revolute"><parent link="base"/><child link="spare"/></joint>
  <joint name="plate_joint" type="planar"><parent link="base"/><child link="plate"/><origin xyz="0 0 -1"/></joint>
  <joint name="loose_joint" type="floating"><parent link="base"/><child link="loose"/></joint>
  <ros2_control name="toy" type="system"><joint name="lift"/><joint name="not_in_the_tree"/></ros2_control>
</robot>
"""


def check(transform: Transform, translation: Iterable[float], rotation: np.ndarray) -> None:
    assert math.isclose(float(np.linalg.norm(transform.rotation)), 1.0, abs_tol=1e-12)
    np.testing.assert_allclose(transform.translation, list(translation), rtol=0, atol=1e-12)
    np.testing.assert_allclose(matrix(transform)[:3, :3], rotation, rtol=0, atol=1e-12)


def test_hand_written_urdf() -> None:
    tree = TreeTransforms(TOY, "toy/")
    assert tree.moving_joints == ("lift", "spare_joint", "turn")

    static = {t.child: t for t in tree.static()}
    assert set(static) == {"toy/sensor", "toy/plate"}          # planar joints are fixed ones; floating are left out
    assert static["toy/sensor"].parent == "toy/arm"
    check(static["toy/sensor"], (0.01, 0.02, 0.03), rpy(0.3, 0.2, 0.1))
    check(static["toy/plate"], (0, 0, -1), np.eye(3))

    lift, turn = 0.25, 0.6
    moved = {t.child: t for t in tree.moving({"lift": lift, "turn": turn, "unrelated": 9.0})}
    assert set(moved) == {"toy/slider", "toy/arm", "toy/finger"}   # spare_joint has no position: left out
    # The axis 0 0 2 is a unit axis along z of the joint frame, which the origin turns a quarter about z.
    check(moved["toy/slider"], (0.1, 0, 0.2 + lift), rz(math.pi / 2))
    check(moved["toy/arm"], (0.3, 0, 0), rpy(0.2, -0.4, 0.7) @ about((1, 1, 0), turn))
    check(moved["toy/finger"], (0, 0.05, 0), about((0, 1, 0), 2 * turn + 0.1))
    assert [t.child for t in tree.moving({"lift": lift, "turn": turn})] == ["toy/finger", "toy/slider", "toy/arm"]

    only_lift = tree.moving({"lift": -lift})
    assert [t.child for t in only_lift] == ["toy/slider"]                # the mimic's source is missing too
    check(only_lift[0], (0.1, 0, 0.2 - lift), rz(math.pi / 2))
    # A position reported for the mimic joint itself is used as it is, as robot_state_publisher does.
    finger = {t.child: t for t in tree.moving({"turn": turn, "finger_joint": -0.5})}["toy/finger"]
    check(finger, (0, 0.05, 0), about((0, 1, 0), -0.5))
    assert tree.moving({}) == []


@pytest.mark.parametrize(("origin", "found"), [('xyz="0 0 zero"', "0 0 zero"), ('rpy="0 0"', "0 0"),
                                               ('xyz="0 0 nan"', "0 0 nan")])
def test_malformed_origin_names_the_joint(origin: str, found: str) -> None:
    urdf = TOY.replace('<origin xyz="0.3 0 0" rpy="0.2 -0.4 0.7"/>', f"<origin {origin}/>")
    with pytest.raises(ConfigError) as raised:
        TreeTransforms(urdf, "")
    assert "'turn'" in raised.value.summary and found in raised.value.why


def test_zero_axis_is_refused() -> None:
    with pytest.raises(ConfigError, match="lift"):
        TreeTransforms(TOY.replace('<axis xyz="0 0 2"/>', '<axis xyz="0 0 0"/>'), "")


def test_tf_message_round_trips_through_cdr(indy7: tuple[str, dict[str, tuple[str, str, str]]]) -> None:
    urdf, _ = indy7
    tree = TreeTransforms(urdf, PREFIX)
    transforms = [*tree.static(), *tree.moving({name: 0.2 * i - 0.5 for i, name in enumerate(tree.moving_joints)})]
    lib = library()
    stamp_ns = 1_700_000_123_456_789_012
    message = tf_message(lib, transforms, stamp_ns)
    back = lib.store.deserialize_cdr(message.serialize(), "tf2_msgs/msg/TFMessage")
    assert len(back.transforms) == len(transforms) == 7
    for sent, received in zip(transforms, back.transforms, strict=True):
        assert (received.header.stamp.sec, received.header.stamp.nanosec) == (1_700_000_123, 456_789_012)
        assert (received.header.frame_id, received.child_frame_id) == (sent.parent, sent.child)
        moved, turned = received.transform.translation, received.transform.rotation
        assert (moved.x, moved.y, moved.z) == sent.translation
        assert (turned.x, turned.y, turned.z, turned.w) == sent.rotation
    empty = tf_message(lib, [], stamp_ns).serialize()
    assert lib.store.deserialize_cdr(empty, "tf2_msgs/msg/TFMessage").transforms == []
