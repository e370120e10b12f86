"""Description packages in the shapes real arms come in, made by `plem create-description` and edited at test time:
a continuous joint (Kinova Gen3's default) and a joint whose range excludes 0 (Franka FR3's joint4)."""

from __future__ import annotations

import re
from pathlib import Path

from plem.description.scaffold import create_package

JOINTS = tuple(f"joint{i}" for i in range(1, 7))
#: FR3's joint4 range, given here to the generated arm's joint4.
FR3_JOINT4 = (-3.04, -0.15)


def generated(folder: Path, name: str) -> tuple[Path, Path, Path]:
    """A generated 6-axis package with an SRDF: its root, URDF xacro and joint_limits.yaml."""
    create_package(folder, name, 6, with_moveit=True)
    root = folder / f"{name}_description"
    return root, root / "urdf" / f"{name}.urdf.xacro", root / "config" / "joint_limits.yaml"


def _edit(path: Path, pattern: str, replacement: str) -> None:
    text, count = re.subn(pattern, replacement, path.read_text(encoding="utf-8"))
    assert count == 1, f"{pattern!r} not found once in {path}"
    path.write_text(text, encoding="utf-8")


def narrowed(root: Path, joint: str, low: float, high: float) -> Path:
    """joint_limits.yaml gives `joint` the range [low, high] (validation refuses it wider than the URDF's)."""
    _edit(root / "config" / "joint_limits.yaml",
          rf"(  {joint}:\n    has_position_limits: true\n)    min_position: \S+\n    max_position: \S+\n",
          rf"\1    min_position: {low}\n    max_position: {high}\n")
    return root


def continuous_wrist(folder: Path, name: str = "spin") -> Path:
    """joint6 is continuous: no position limits in the URDF, has_position_limits: false in joint_limits.yaml."""
    root, urdf, limits = generated(folder, name)
    _edit(urdf, r'(<joint name="\$\{pfx\}joint6" type=")revolute(">(?:.|\n)*?<limit )lower="[^"]*" upper="[^"]*" ',
          r"\1continuous\2")
    _edit(limits, r"(  joint6:\n)    has_position_limits: true\n    min_position: \S+\n    max_position: \S+\n",
          r"\1    has_position_limits: false\n")
    return root


def zero_outside_joint4(folder: Path, name: str = "bent", home: float | None = None) -> Path:
    """joint4's range is FR3's joint4 range, which excludes 0. The SRDF keeps no `zero` state; with `home`, its home
    state has joint4 there, without it the SRDF has no home."""
    root, urdf, _ = generated(folder, name)
    low, high = FR3_JOINT4
    _edit(urdf, r'(<joint name="\$\{pfx\}joint4" type="revolute">(?:.|\n)*?<limit )lower="[^"]*" upper="[^"]*"',
          rf'\1lower="{low}" upper="{high}"')
    narrowed(root, "joint4", low, high)
    srdf = root / "srdf" / f"{name}.srdf"
    _edit(srdf, r'  <group_state name="zero" group="arm">(?:.|\n)*?</group_state>\n', "")
    if home is None:
        _edit(srdf, r'  <group_state name="home" group="arm">(?:.|\n)*?</group_state>\n', "")
    else:
        _edit(srdf, r'(<group_state name="home" group="arm">(?:.|\n)*?<joint name="joint4" value=")[^"]*"',
              rf'\g<1>{home}"')
    return root
