"""Every input a user can get wrong ends in ERROR/WHAT/WHY/HOW and exit 1 (2 for usage), never a traceback."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib.metadata import version
from pathlib import Path

import pytest

from plem.description.scaffold import create_package
from plem.robot import RobotProfile
from tests.e2e.cli import plem_executable, run_plem

REPOSITORY = Path(__file__).resolve().parents[2]
Setup = Callable[[Path, Path], None]   # (tmp_path, PLEM_HOME)


def _nothing(tmp: Path, home: Path) -> None:
    """No files needed."""


def _profile(text: str) -> Setup:
    def write(tmp: Path, home: Path) -> None:
        (home / "profiles").mkdir(parents=True)
        (home / "profiles" / "X1.json").write_text(text)
    return write


def _profile_link(target: str) -> Setup:
    def link(tmp: Path, home: Path) -> None:
        (home / "profiles").mkdir(parents=True)
        os.symlink(target, home / "profiles" / "X1.json")
    return link


def _profile_fifo(tmp: Path, home: Path) -> None:
    (home / "profiles").mkdir(parents=True)
    os.mkfifo(home / "profiles" / "X1.json")


def _saved_profile(tmp: Path, home: Path) -> None:
    RobotProfile(robot_serial="X1", joint_offsets=[1] * 6).save(home / "profiles" / "X1.json")


def _regular_file(tmp: Path, home: Path) -> None:
    (tmp / "file").write_text("not a folder\n")


def _robots(text: str | bytes) -> Setup:
    def write(tmp: Path, home: Path) -> None:
        data = text.encode() if isinstance(text, str) else text
        (tmp / "robots.yaml").write_bytes(data)
    return write


def _robots_fifo(tmp: Path, home: Path) -> None:
    os.mkfifo(tmp / "robots.yaml")


def _package(compat: str) -> Setup:
    def write(tmp: Path, home: Path) -> None:
        root = create_package(tmp, "bot", 6).root
        (root / "PLEM_COMPAT_VERSION").write_text(compat)
    return write


@dataclass(frozen=True)
class Row:
    """One bad input: the command line (`{tmp}` is the test's folder), its environment, files made first."""

    argv: tuple[str, ...]
    expected: str
    code: int = 1
    env: dict[str, str] = field(default_factory=dict)
    setup: Setup = _nothing


PROFILE_CREATE = ("profile", "create", "--serial", "X1", "--offsets", "1,2,3,4,5,6")
ROBOTS = ("launch", "robots:={tmp}/robots.yaml")
ROWS = {
    # 1. create-description: a name too long for a file name, an --output that is no folder
    "name_too_long": Row(("create-description", "--name", "a" * 300, "--dof", "6", "--output", "{tmp}/out"),
                         "name has 300 characters; at most 222 fit"),
    "output_is_a_file": Row(("create-description", "--name", "bot", "--dof", "6", "--output", "{tmp}/file"),
                            "is a regular file", setup=_regular_file),
    "output_in_proc": Row(("create-description", "--name", "bot", "--dof", "6", "--output", "/proc/1"),
                          "Cannot write the package to /proc/1/bot_description"),
    # 2. robot profiles that are too large, too deep, too long a number, a device or a FIFO
    "profile_100000_levels": Row(("profile", "show", "X1"), "of at most 64.0 KiB",
                                 setup=_profile("[" * 100_000)),
    "profile_5000_levels": Row(("profile", "show", "X1"), "nest too deeply", setup=_profile("[" * 5000)),
    "profile_5000_digits": Row(("profile", "show", "X1"), "a number has more than",
                               setup=_profile('{"robot_serial": "X1", "joint_offsets": [' + "7" * 5000 + "]}")),
    "profile_dev_zero": Row(("profile", "show", "X1"), "is a character device", setup=_profile_link("/dev/zero")),
    "profile_fifo": Row(("profile", "show", "X1"), "is a FIFO", setup=_profile_fifo),
    # 3. PLEM_HOME that is not a folder
    **{f"plem_home_{name}_{'_'.join(argv[:2])}": Row(argv, "PLEM_HOME is not a folder", env={"PLEM_HOME": home},
                                                      setup=_regular_file)
       for name, home in (("file", "{tmp}/file"), ("dev_null", "/dev/null"))
       for argv in (("profile", "list"), PROFILE_CREATE, ("config", "show"))},
    # 4. a compat version no int should be made of
    "compat_5000_digits": Row(("validate", "{tmp}/bot_description"), "each part at most 9 digits",
                              setup=_package("1." + "7" * 5000 + ".0\n")),
    # 5. robots files of the wrong shape or kind
    "robots_list_as_robot_id": Row(ROBOTS, "robot_id is a list",
                                   setup=_robots("robots:\n  - {robot_id: [a, b], bus: mock}\n")),
    "robots_deep": Row(ROBOTS, "nest more than 64 deep", setup=_robots("robots: " + "[" * 200 + "]" * 200)),
    "robots_not_utf8": Row(ROBOTS, "is not UTF-8", setup=_robots(b"robots:\n  - {robot_id: \xff}\n")),
    "robots_dev_zero": Row(("launch", "robots:=/dev/zero"), "is a character device"),
    "robots_fifo": Row(ROBOTS, "is a FIFO", setup=_robots_fifo),
    "robots_not_a_list": Row(ROBOTS, "robots.yaml:1: robots: is the single value 5", setup=_robots("robots: 5\n")),
    # 6. creating a profile that exists
    "profile_exists": Row(PROFILE_CREATE, "rerun with --force", setup=_saved_profile),
    # 7. durations that are not a number of seconds
    "topic_list_timeout_nan": Row(("topic", "list", "--timeout", "nan"), "--timeout must be", code=2),
    "topic_echo_timeout_nan": Row(("topic", "echo", "/x", "--timeout", "nan"), "--timeout must be", code=2),
    "topic_hz_duration_nan": Row(("topic", "hz", "/x", "--duration", "nan"), "--duration must be", code=2),
    "topic_hz_duration_negative": Row(("topic", "hz", "/x", "--duration", "-1"), "--duration is -1.0", code=2),
    "topic_hz_timeout_inf": Row(("topic", "hz", "/x", "--timeout", "inf"), "--timeout is inf", code=2),
    # 8. a negative domain id
    "domain_negative": Row(("config", "show"), "cannot be negative", env={"ROS_DOMAIN_ID": "-1"}),
    # a home directory of a user the system does not know; digits other than 0-9 in a number
    "validate_unknown_home": Row(("validate", "~nosuchuser0/bot_description"), "there is no user 'nosuchuser0'"),
    "validate_override_unknown_home": Row(("validate", "indy7_v2_description", "urdf_file:=~nosuchuser0/a.urdf"),
                                          "there is no user 'nosuchuser0'"),
    "environment_superscript_digit": Row(("config", "show"), "PLEM_CYCLE_TIME_US is '²'",
                                         env={"PLEM_CYCLE_TIME_US": "²"}),
    # 10. validate's name:=value overrides
    "validate_unknown_override": Row(("validate", "indy7_v2_description", "urdf:=x"), "did you mean urdf_file",
                                     code=2),
}


@pytest.mark.parametrize("row", ROWS.values(), ids=ROWS.keys())
def test_bad_input_is_explained(row: Row, tmp_path: Path, isolated_environment: Path):
    row.setup(tmp_path, isolated_environment)
    argv = [word.format(tmp=tmp_path) for word in row.argv]
    env = {name: value.format(tmp=tmp_path) for name, value in row.env.items()}
    result = run_plem(*argv, env=env, timeout=30)
    output = result.stdout + result.stderr
    assert result.returncode == row.code, output
    for label in ("WHAT:", "WHY:", "HOW:"):
        assert label in output
    assert "Traceback" not in output and "Internal error" not in output
    assert row.expected in output


def test_concurrent_creates_of_one_profile_leave_exactly_one(isolated_environment: Path):
    """Eight `plem profile create` of one serial at once: one saves, the others are told it exists."""
    processes = [subprocess.Popen([plem_executable(), "profile", "create", "--serial", "RACE1",
                                   "--offsets", ",".join([str(index)] * 6)],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                 for index in range(1, 9)]
    results = [(index, process.communicate(timeout=60), process.returncode)
               for index, process in enumerate(processes, start=1)]
    winners = [index for index, (out, _), code in results if code == 0 and "Saved" in out]
    assert len(winners) == 1, results
    for index, (out, err), code in results:
        if index != winners[0]:
            assert code == 1 and "already exists" in err and "--force" in err and "Saved" not in out, (out, err)
    folder = isolated_environment / "profiles"
    assert json.loads((folder / "RACE1.json").read_text())["joint_offsets"] == [winners[0]] * 6
    assert os.listdir(folder) == ["RACE1.json"]   # no temporary file left behind


def test_force_still_replaces(isolated_environment: Path):
    assert run_plem(*PROFILE_CREATE).returncode == 0
    forced = run_plem("profile", "create", "--serial", "X1", "--offsets", "9,9,9,9,9,9", "--force")
    assert forced.returncode == 0 and "Saved" in forced.stdout
    assert RobotProfile.load(isolated_environment / "profiles" / "X1.json").joint_offsets == [9] * 6


def test_version_comes_from_the_package_metadata():
    result = run_plem("--version")
    assert result.returncode == 0
    assert result.stdout == f"plem {version('plem')}\n"


def test_validate_accepts_the_override_its_hint_names(tmp_path: Path):
    root = create_package(tmp_path, "bot", 6).root
    (root / "urdf" / "copy.urdf.xacro").write_text((root / "urdf" / "bot.urdf.xacro").read_text())
    ambiguous = run_plem("validate", str(root))
    assert ambiguous.returncode == 1
    hint = re.search(r"pick one with (urdf_file:=\S+)", ambiguous.stderr)
    assert hint, ambiguous.stderr
    chosen = run_plem("validate", str(root), hint.group(1))
    assert chosen.returncode == 0, chosen.stdout + chosen.stderr
    assert "OK: bot_description" in chosen.stdout


def _readme_example() -> str:
    blocks = re.findall(r"```python\n(.*?)```", (REPOSITORY / "README.md").read_text(), re.DOTALL)
    return next(block for block in blocks if "load_config(" in block)


def test_readme_load_config_example_runs_from_the_repository_root():
    result = subprocess.run([sys.executable, "-c", _readme_example()], cwd=REPOSITORY, capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert "2.617993878" in result.stdout


def test_missing_config_file_is_one_error_without_a_chain(tmp_path: Path):
    script = "from plem.core.config import load_config\nload_config('config/robot.yaml', 'robot.timeout', int)\n"
    result = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 1
    assert result.stderr.count("Traceback") == 1 and "During handling" not in result.stderr
    assert "plem.errors.ConfigError: ERROR: File not found: config/robot.yaml" in result.stderr
