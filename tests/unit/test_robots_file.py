"""robots:=FILE.yaml: every problem of the file reported at once, each with file:line."""

import os
from pathlib import Path

import pytest

from plem.errors import ConfigError, MultipleErrors
from plem.launch.robots_file import load_robots


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "robots.yaml"
    path.write_text(text)
    return path


def test_all_problems_are_collected_with_their_lines(tmp_path: Path):
    path = write(tmp_path, "robots:\n"
                           "  - {robot_id: [a, b], bus: mock}\n"
                           "  - {robot_id: x, bus: {a: 1}}\n"
                           "  - 5\n"
                           "  - {robot_id: x, colour: red}\n")
    with pytest.raises(MultipleErrors) as error:
        load_robots(path, {})
    whys = [problem.why for problem in error.value.errors]
    assert whys == [f"{path}:2: robot_id is a list", f"{path}:3: bus is a mapping",
                    f"{path}:4: robot 2 is the single value 5", f"{path}:5: unknown: colour",
                    f"{path}:5: robots 1 and 3 are both x"]


@pytest.mark.parametrize(("text", "why"), [
    ("", "the file is empty"),
    ("x: 1\n", "no robots: key (keys: x)"),
    ("robots: 5\n", "robots.yaml:1: robots: is the single value 5"),
    ("robots:\n  - {robot_id: a, bus: }\n", "robots.yaml:2: bus is empty"),
])
def test_shape_problems_name_what_was_found(tmp_path: Path, text: str, why: str):
    with pytest.raises(ConfigError) as error:
        load_robots(write(tmp_path, text), {})
    assert why in error.value.why


@pytest.mark.parametrize(("make", "why"), [
    (lambda path: os.mkfifo(path), "is a FIFO"),
    (lambda path: os.symlink("/dev/zero", path), "is a character device"),
    (lambda path: path.write_bytes(b"robots:\n  - {robot_id: \xff}\n"), "is not UTF-8"),
    (lambda path: path.write_text("robots: " + "[" * 100 + "]" * 100), "nest more than 64 deep"),
])
def test_files_that_cannot_be_read_are_refused_unread(tmp_path: Path, make, why: str):
    path = tmp_path / "robots.yaml"
    make(path)
    with pytest.raises(ConfigError) as error:
        load_robots(path, {})
    assert why in error.value.why and "robots" in error.value.summary
