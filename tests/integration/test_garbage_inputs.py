"""Property tests: garbage in any file of a description package never escapes as anything but a PlemError.

Each example writes one generated file into a fresh copy of indy7_v2_description and validates it;
validate_package must return a report (or raise a PlemError), and garbage in a required file (the URDF,
joint_limits.yaml, PLEM_COMPAT_VERSION) must be reported as at least one error.
"""

from __future__ import annotations

import re
import string
from xml.sax.saxutils import quoteattr

import pytest
import yaml
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.description.compat import PROTOCOL_VERSION
from plem.description.validate import ValidationReport, validate_package
from plem.errors import PlemError
from tests.integration.packages import copy_builtin

ROBOT = "indy7_v2"
# target -> (file relative to the package root, required by the protocol)
TARGETS = {
    "joint_limits": ("config/joint_limits.yaml", True),
    "controllers": ("config/controllers.yaml", False),
    "kinematics": ("config/kinematics.yaml", False),
    "srdf": ("srdf/indy7_v2.srdf", False),
    "urdf": ("urdf/indy7_v2.urdf.xacro", True),
    "compat": ("PLEM_COMPAT_VERSION", True),
}
YAML_TARGETS = ("joint_limits", "controllers", "kinematics")
_MAJOR = PROTOCOL_VERSION.split(".")[0]
ACCEPTABLE_COMPAT = re.compile(rf"{_MAJOR}\.(0|[1-9]\d*)\.(0|[1-9]\d*)(?:-[0-9A-Za-z.-]+)?(?:\+[0-9A-Za-z.-]+)?")

# No shrink phase: shrinking a failure costs hundreds of validations and would break the time budget.
# The minimal inputs the properties led to are kept in MINIMAL_GARBAGE below; to shrink a new failure,
# add Phase.shrink here while investigating it.
PHASES = (Phase.explicit, Phase.reuse, Phase.generate)
FAST = settings(max_examples=30, deadline=None, database=None, phases=PHASES)
THOROUGH = settings(max_examples=60, deadline=None, database=None, phases=PHASES)


# ---------------------------------------------------------------- strategies

# text: any unicode that can be written as UTF-8, plus random bytes decoded as Latin-1
TEXT = st.one_of(st.text(st.characters(blacklist_categories=("Cs",)), max_size=400),
                 st.binary(max_size=400).map(lambda data: data.decode("latin-1")))
RAW_BYTES = st.binary(min_size=1, max_size=400)

SCALARS = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(),
                    st.text(max_size=20), st.sampled_from(["joint0", "joint5", "arm", "tcp", "max_velocity"]))
YAML_VALUES = st.recursive(SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(st.one_of(st.text(max_size=15), st.integers(), st.booleans()),
                                                 inner, max_size=5)), max_leaves=25)

# XML built from the vocabulary of URDF, SRDF, ros2_control and xacro, with values that stress the checks
NAMES = st.sampled_from(["", "link0", "link1", "link6", "tcp", "a", "b", "joint0", "joint5", "tcp_joint", "arm"])
VALUES = st.one_of(
    NAMES,
    st.sampled_from(["revolute", "prismatic", "continuous", "fixed", "floating", "planar", "bogus", "position",
                     "velocity", "hardware/HardwareInterface", "0", "-1", "1e308", "nan", "inf", "-inf", "0 0 1",
                     "${pi/2}", "${1/0}", "${nope}", "${pfx}", "$(arg prefix)", "$(arg nope)", "$(find nope)",
                     "$(find indy7_v2_description)", "package://nope/x.stl", "package://indy7_v2_description/x.stl",
                     "file:///nonexistent/x.stl", "prefix:=''", "*shape", "true", "false"]),
    st.text(st.characters(blacklist_categories=("Cs", "Cc")), max_size=12))
NS = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'


@st.composite
def _tagged(draw, tag: str, attributes: tuple[str, ...], children: tuple) -> str:
    """<tag> with a random subset of `attributes` and up to four children drawn from `children`."""
    chosen = draw(st.lists(st.sampled_from(attributes), unique=True)) if attributes else []
    attrs = "".join(f" {name}={quoteattr(draw(VALUES))}" for name in chosen)
    body = "".join(draw(st.lists(st.one_of(*children), max_size=4))) if children else ""
    return f"<{tag}{attrs}>{body}</{tag}>" if body else f"<{tag}{attrs}/>"


def tag(name: str, attributes: str = "", *children) -> st.SearchStrategy[str]:
    return _tagged(name, tuple(attributes.split()), children)


ANY_TAG = st.sampled_from(["robot", "link", "joint", "parent", "child", "limit", "mimic", "origin", "axis", "visual",
                           "geometry", "mesh", "ros2_control", "hardware", "plugin", "group", "chain", "group_state",
                           "xacro:property", "xacro:arg", "xacro:if", "xacro:macro", "xacro:insert_block",
                           "xacro:element", "xacro:attribute"])
ANY_ATTRIBUTES = ("name type link lower upper velocity effort joint filename value group base_link tip_link "
                  "default params")
ELEMENTS = st.recursive(ANY_TAG.flatmap(lambda name: tag(name, ANY_ATTRIBUTES)),
                        lambda inner: ANY_TAG.flatmap(lambda name: tag(name, ANY_ATTRIBUTES, inner)), max_leaves=12)
URDF_PARTS = st.one_of(
    tag("link", "name", tag("visual", "", tag("geometry", "", tag("mesh", "filename")))),
    tag("joint", "name type", tag("parent", "link"), tag("child", "link"), tag("limit", "lower upper velocity effort"),
        tag("mimic", "joint")),
    tag("ros2_control", "name", tag("hardware", "", tag("plugin")),
        tag("joint", "name", tag("command_interface", "name"), tag("state_interface", "name"))),
    tag("xacro:arg", "name default"),
    ELEMENTS)
SRDF_PARTS = st.one_of(
    tag("group", "name", tag("link", "name"), tag("joint", "name"), tag("chain", "base_link tip_link"),
        tag("group", "name")),
    tag("group_state", "name group", tag("joint", "name value")),
    tag("disable_collisions", "link1 link2 reason"),
    ELEMENTS)
XML_TEXT = st.text(alphabet='<>/="\' robotlinkjointxacro:${}()\n', max_size=300)


@st.composite
def xml_documents(draw, parts: st.SearchStrategy[str]) -> str:
    """A <robot> of random parts; sometimes cut or spliced so it is no longer well-formed."""
    name = draw(st.sampled_from(['name="indy7_v2"', 'name="other"', ""]))
    body = "\n".join(draw(st.lists(parts, max_size=10)))
    text = f'<?xml version="1.0"?>\n<robot {name} {NS}>\n{body}\n</robot>\n'
    damage = draw(st.sampled_from(["none", "none", "truncate", "splice"]))
    if damage == "truncate":
        text = text[:draw(st.integers(0, len(text)))]
    elif damage == "splice":
        at = draw(st.integers(0, len(text)))
        text = text[:at] + draw(st.sampled_from(["<", ">", "&", '"', "</link>", "<joint", "]]>", "\x00"])) + text[at:]
    return text


@st.composite
def perturbed_yaml(draw, target: str) -> str:
    """The package's real file (or a valid controllers.yaml) with some values or keys replaced by garbage."""
    data = _valid_yaml(target)
    for _ in range(draw(st.integers(1, 4))):
        container, key = _random_path(draw, data)
        if container is None:
            break
        action = draw(st.sampled_from(["value", "delete", "add"]))
        if action == "value":
            container[key] = draw(YAML_VALUES)
        elif action == "delete" and isinstance(container, dict):
            container.pop(key, None)
        elif isinstance(container, dict):
            container[draw(st.text(max_size=10))] = draw(YAML_VALUES)
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True)


def _valid_yaml(target: str):
    if target == "controllers":
        return {"controller_manager": {"ros__parameters": {"update_rate": 1000}},
                "joint_trajectory_controller": {"ros__parameters": {"joints": [f"joint{i}" for i in range(6)]}}}
    path = BUILTIN_PACKAGES_DIR / f"{ROBOT}_description" / TARGETS[target][0]
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def _random_path(draw, node):
    """Walk down to a random (container, key) pair inside the document."""
    container, key = None, None
    while isinstance(node, (dict, list)) and node:
        keys = list(node) if isinstance(node, dict) else list(range(len(node)))
        container, key = node, draw(st.sampled_from(keys))
        node = node[key]
        if draw(st.booleans()):
            break
    return container, key


# ---------------------------------------------------------------- running an example

def validate_with(tmp_path_factory: pytest.TempPathFactory, target: str,
                  content: str | bytes) -> ValidationReport | None:
    """Write `content` into the target file of a fresh package copy and validate; None if a PlemError was raised."""
    folder = tmp_path_factory.mktemp("garbage")
    root = copy_builtin(ROBOT, folder)
    path = root / TARGETS[target][0]
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PLEM_PACKAGE_PATH", str(folder))
        try:
            return validate_package(root)
        except PlemError:
            return None
        # anything else propagates and fails the property


def check(report: ValidationReport | None, target: str, content: str | bytes) -> None:
    required = TARGETS[target][1]
    if report is None or not required:
        return
    if target == "compat":
        text = content.decode("utf-8", "replace") if isinstance(content, bytes) else content
        if ACCEPTABLE_COMPAT.fullmatch(text.strip()):
            return  # not garbage after all
    assert report.findings.errors, f"garbage in {target} was not reported: {report.findings.codes()}"


# ---------------------------------------------------------------- properties

@pytest.mark.parametrize("target", list(TARGETS))
@FAST
@given(content=TEXT)
def test_random_text(tmp_path_factory, target, content):
    check(validate_with(tmp_path_factory, target, content), target, content)


@pytest.mark.parametrize("target", list(TARGETS))
@FAST
@given(content=RAW_BYTES)
def test_random_bytes(tmp_path_factory, target, content):
    check(validate_with(tmp_path_factory, target, content), target, content)


@pytest.mark.parametrize("target", YAML_TARGETS)
@FAST
@given(data=YAML_VALUES)
def test_random_yaml_structures(tmp_path_factory, target, data):
    content = yaml.safe_dump(data, allow_unicode=True)
    check(validate_with(tmp_path_factory, target, content), target, content)


@pytest.mark.slow
@pytest.mark.parametrize("target", YAML_TARGETS)
@THOROUGH
@given(data=st.data())
def test_perturbed_yaml(tmp_path_factory, target, data):
    """Near-valid files reach the per-key checks; they may be valid, so only escaping exceptions count."""
    validate_with(tmp_path_factory, target, data.draw(perturbed_yaml(target)))


@pytest.mark.slow
@THOROUGH
@given(content=st.one_of(xml_documents(URDF_PARTS), XML_TEXT))
def test_random_urdf_xml(tmp_path_factory, content):
    check(validate_with(tmp_path_factory, "urdf", content), "urdf", content)


@pytest.mark.slow
@THOROUGH
@given(content=st.one_of(xml_documents(SRDF_PARTS), XML_TEXT))
def test_random_srdf_xml(tmp_path_factory, content):
    check(validate_with(tmp_path_factory, "srdf", content), "srdf", content)


PACKAGE_NAME_CHARACTERS = string.ascii_letters + string.digits + "_- "


@settings(max_examples=40, deadline=None, database=None, phases=PHASES)
@given(name=st.one_of(st.text(PACKAGE_NAME_CHARACTERS, min_size=1, max_size=40),
                      st.text(PACKAGE_NAME_CHARACTERS, min_size=200, max_size=400)))
def test_random_package_names(tmp_path_factory, name):
    """A name that is no package (run from an empty folder, so it is no path either) is a PlemError."""
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(tmp_path_factory.mktemp("empty"))
        with pytest.raises(PlemError):
            validate_package(name)


LONG = "a" * 300  # longer than a file name may be (255)
MESH_LINK = ('<robot name="x"><link name="a"><visual><geometry><mesh filename="{uri}"/></geometry></visual></link>'
             "</robot>")
NAMELESS_JOINT = ('<robot name="x"><link name="a"/><link name="b"/><joint type="revolute"><parent link="a"/>'
                  '<child link="b"/><limit lower="0" upper="1" velocity="1"/></joint></robot>')
MINIMAL_GARBAGE = {
    "srdf_not_utf8": ("srdf", b'<robot name="indy7_v2">\x80</robot>'),
    "controllers_joint_is_a_list": ("controllers", "jtc:\n  ros__parameters:\n    joints: [[]]\n"),
    "controllers_joint_is_a_mapping": ("controllers", "jtc:\n  ros__parameters:\n    joints: [{a: 1}]\n"),
    "urdf_nameless_link": ("urdf", '<robot name="x"><link/><link name="a"/></robot>'),
    "urdf_nameless_joint": ("urdf", NAMELESS_JOINT),
    "urdf_nameless_interface": ("urdf", '<robot name="x"><ros2_control><joint><command_interface/></joint>'
                                        "</ros2_control></robot>"),
    "urdf_mesh_name_too_long": ("urdf", MESH_LINK.format(uri=f"{LONG}.stl")),
    "urdf_mesh_package_too_long": ("urdf", MESH_LINK.format(uri=f"package://{LONG}/x.stl")),
}


@pytest.mark.parametrize("target, content", list(MINIMAL_GARBAGE.values()), ids=list(MINIMAL_GARBAGE))
def test_minimal_garbage(tmp_path_factory, target, content):
    """Small inputs found by the properties above (or next to what they found), kept as fixed examples."""
    check(validate_with(tmp_path_factory, target, content), target, content)
