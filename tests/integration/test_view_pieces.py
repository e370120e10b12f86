"""The view's pieces on real files and a real planner: the model drawn from a URDF, what the page receives of it,
the description a launch shares in /dev/shm, the planner's answer to a view, and the page's text."""

from __future__ import annotations

import json
import os
import struct
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from plem.control.limits import ArmLimits
from plem.description.validate import validate_package
from plem.errors import PlemError
from plem.ipc.robot_description import (
    DescriptionUnavailable,
    SharedDescription,
    description_path,
    read_description,
    remove_description,
    share_description,
)
from plem.planning import Box, Pose, SceneObject
from plem.planning.goals import JointGoal
from plem.planning.planner import Planner
from plem.planning.service import PlannerService
from plem.view.feed import drives_text
from plem.view.model import ViewModel
from plem.view.readouts import plain
from plem.view.scene import ArmScene
from plem.view.server import start_server
from tests.e2e.cli import run_plem

INDY7 = "indy7_v2_description"


@pytest.fixture(scope="module")
def indy7() -> tuple[str, tuple[str, ...]]:
    report = validate_package(INDY7)
    assert report.urdf is not None and report.urdf_xml is not None
    return report.urdf_xml, tuple(joint.name for joint in report.urdf.actuated_joints)


def test_the_model_maps_the_arm_onto_its_urdf_and_finds_base_and_tool(indy7: tuple[str, tuple[str, ...]]) -> None:
    urdf, joints = indy7
    model = ViewModel(urdf, tuple(reversed(joints)))
    assert (model.base_link, model.tool_link) == ("link0", "tcp") and model.missing == []
    configuration = model.configuration(np.arange(len(joints), dtype=float))
    np.testing.assert_array_equal(configuration, np.arange(len(joints))[::-1])


def test_a_missing_mesh_is_listed_and_the_arm_still_loads(indy7: tuple[str, tuple[str, ...]]) -> None:
    urdf, joints = indy7
    visual = urdf.index("<geometry>", urdf.index("<visual>"))        # the first link's visual geometry
    end = urdf.index("</geometry>", visual)
    broken = urdf[:visual] + '<geometry><mesh filename="package://no_such_package/meshes/a.stl"/>' + urdf[end:]
    model = ViewModel(broken, joints)
    assert model.missing == ["package://no_such_package/meshes/a.stl"]
    assert len(model.load().actuated_joint_names) == len(joints)


def test_meshes_of_the_package_are_drawn(indy7: tuple[str, tuple[str, ...]], tmp_path: Path) -> None:
    urdf, joints = indy7
    meshes = tmp_path / "arm_meshes" / "meshes"
    meshes.mkdir(parents=True)
    trimesh.creation.box((0.1, 0.2, 0.3)).export(meshes / "base.stl")
    visual = urdf.index("<geometry>", urdf.index("<visual>"))
    end = urdf.index("</geometry>", visual)
    with_mesh = urdf[:visual] + '<geometry><mesh filename="package://arm_meshes/meshes/base.stl"/>' + urdf[end:]
    model = ViewModel(with_mesh, joints, {"arm_meshes": str(tmp_path / "arm_meshes")})
    assert model.missing == []
    extents = sorted(tuple(np.round(mesh.extents, 3)) for mesh in model.load().scene.geometry.values())
    assert (0.1, 0.2, 0.3) in extents


def _glb_material(mesh: trimesh.Trimesh) -> dict:
    """The glTF material a browser gets for `mesh`: viser sends each URDF mesh as GLB exported by trimesh."""
    glb = mesh.export(file_type="glb")
    (length,) = struct.unpack_from("<I", glb, 12)
    materials = json.loads(glb[20:20 + length]).get("materials") or [{}]
    return dict(materials[0].get("pbrMetallicRoughness", {}))


def test_the_arm_is_drawn_matte_in_its_own_colours(indy7: tuple[str, tuple[str, ...]], tmp_path: Path) -> None:
    """A mesh without a material is bare metal in glTF (black under plain lights): every mesh gets a non-metallic
    one in its URDF colour, or keeps its texture."""
    urdf, joints = indy7
    materials = [_glb_material(mesh) for mesh in ViewModel(urdf, joints).load().scene.geometry.values()]
    assert materials and all(material.get("metallicFactor") == 0.0 for material in materials)
    colours = {tuple(np.round(material["baseColorFactor"][:3], 2)) for material in materials}
    assert colours == {(0.89, 0.89, 0.89), (0.35, 0.35, 0.37)}      # indy_white and indy_grey of the URDF
    package = tmp_path / "textured" / "meshes"
    package.mkdir(parents=True)
    box = trimesh.creation.box((0.1, 0.1, 0.1))
    box.visual = trimesh.visual.TextureVisuals(
        uv=np.zeros((len(box.vertices), 2)),
        material=trimesh.visual.material.SimpleMaterial(image=Image.new("RGB", (4, 4), "red")))
    box.export(package / "box.obj")
    visual = urdf.index("<geometry>", urdf.index("<visual>"))
    with_mesh = (urdf[:visual] + '<geometry><mesh filename="package://textured/meshes/box.obj"/>'
                 + urdf[urdf.index("</geometry>", visual):])
    model = ViewModel(with_mesh, joints, {"textured": str(tmp_path / "textured")})
    textured = [mesh for mesh in model.load().scene.geometry.values() if np.allclose(mesh.extents, 0.1)]
    assert len(textured) == 1
    glb_material = _glb_material(textured[0])
    assert glb_material["metallicFactor"] == 0.0 and "baseColorTexture" in glb_material


def test_the_page_is_lit_without_an_environment_image(indy7: tuple[str, tuple[str, ...]]) -> None:
    """What a browser receives: no environment image (filtering it freezes a software-drawn page for seconds before
    its first frame) and a hemisphere light in its place."""
    import msgspec
    import viser
    import zstandard
    from websockets.sync.client import connect
    from websockets.typing import Subprotocol

    urdf, joints = indy7
    server = start_server("127.0.0.1", 0, "lights")
    try:
        ArmScene(server, ViewModel(urdf, joints))
        received: dict[str, list[dict]] = {}
        with connect(f"ws://127.0.0.1:{server.get_port()}", max_size=None,
                     subprotocols=[Subprotocol(f"viser-v{viser.__version__}")]) as page:
            deadline = time.monotonic() + 60
            while "GlbMessage" not in received or "HemisphereLightMessage" not in received:
                assert time.monotonic() < deadline, f"the page received only {sorted(received)}"
                frame = page.recv(timeout=60)
                assert isinstance(frame, bytes)
                size, compressed = struct.unpack_from("<QQ", frame)
                window = msgspec.msgpack.decode(zstandard.ZstdDecompressor().decompress(
                    frame[16:16 + compressed], max_output_size=size))
                for message in window["messages"]:
                    received.setdefault(message["type"], []).append(message)
    finally:
        server.stop()
    assert [message["hdri_data"] for message in received["EnvironmentMapMessage"]][-1] is None


def test_joints_the_urdf_lacks_are_refused_with_what_to_do(indy7: tuple[str, tuple[str, ...]]) -> None:
    urdf, joints = indy7
    with pytest.raises(PlemError) as caught:
        ViewModel(urdf, (*joints[:-1], "wrist_9"))
    assert "wrist_9" in caught.value.why and caught.value.how


@pytest.fixture
def robot_id() -> Iterator[str]:
    name = f"view_{uuid.uuid4().hex[:8]}"
    yield name
    description_path(name).unlink(missing_ok=True)


def test_a_shared_description_reads_back_only_while_its_launch_runs(robot_id: str) -> None:
    share_description(robot_id, SharedDescription("<robot name='a'/>", {"pkg": "/opt/pkg"}, os.getpid()))
    assert os.stat(description_path(robot_id)).st_mode & 0o777 == 0o600
    assert read_description(robot_id) == SharedDescription("<robot name='a'/>", {"pkg": "/opt/pkg"}, os.getpid())
    share_description(robot_id, SharedDescription("<robot name='a'/>", {}, 2**22))   # no such process
    with pytest.raises(DescriptionUnavailable) as caught:
        read_description(robot_id)
    assert "has ended" in caught.value.why and f"robot_id:={robot_id}" in caught.value.how
    description_path(robot_id).write_text(json.dumps({"urdf": 1}))
    with pytest.raises(DescriptionUnavailable, match="no description"):
        read_description(robot_id)
    remove_description(robot_id)
    with pytest.raises(DescriptionUnavailable) as caught:
        read_description(robot_id)
    assert "does not exist" in caught.value.why and "--ros" in caught.value.how


def test_the_planner_tells_a_view_only_what_changed() -> None:
    report = validate_package(INDY7)
    assert report.urdf is not None
    joints = tuple(joint.name for joint in report.urdf.actuated_joints)
    planner = Planner.for_package(report, joints, ArmLimits.from_joint_limits(report.limits, joints), 0.001)

    class Still:
        def live_state(self) -> object:
            raise AssertionError("the view's question needs no state")

    service = PlannerService(planner, Still())  # type: ignore[arg-type]
    first = service.handle({"id": 1, "op": "view"})["result"]
    assert first == {"plans": 0, "plan": None, "scene": {"version": 0, "objects": []}}
    planner.scene.add(SceneObject("crate", Box((0.2, 0.2, 0.2)), Pose((0.6, 0.0, 0.1))))
    plan = planner.plan(np.zeros(len(joints)), JointGoal(dict.fromkeys(joints, 0.3)))
    answer = service.handle({"id": 2, "op": "view", "plans_seen": 0, "scene_seen": 0})["result"]
    assert answer["plans"] == 1 and answer["plan"]["duration_s"] == plan.duration_s
    assert [entry["name"] for entry in answer["scene"]["objects"]] == ["crate"]
    again = service.handle({"id": 3, "op": "view", "plans_seen": 1, "scene_seen": answer["scene"]["version"]})
    assert again["result"] == {"plans": 1, "plan": None, "scene": None}


def test_readouts_show_names_as_written_and_drives_compactly() -> None:
    assert plain("free_drive *now*") == "free\\_drive \\*now\\*"
    names = ("j1", "j2")
    same = [{"state": "operation_enabled", "error_code": 0}] * 2
    assert drives_text(True, same, names) == "enabled — all 2: operation enabled"
    mixed = [{"state": "operation_enabled", "error_code": 0}, {"state": "fault", "error_code": 0x7121}]
    text = drives_text(False, mixed, names)
    assert text.startswith("disabled — j1: operation enabled; j2: fault (0x7121")


def test_the_command_explains_what_it_cannot_show() -> None:
    usage = run_plem("view", "--fault", "1")
    assert usage.returncode == 2 and "--robot and --fault need --bag" in usage.stderr
    absent = run_plem("view", f"nobody_{uuid.uuid4().hex[:6]}")
    assert absent.returncode == 1 and "Traceback" not in absent.stderr
    assert "WHAT:" in absent.stderr and "HOW:" in absent.stderr and "plem launch" in absent.stderr
