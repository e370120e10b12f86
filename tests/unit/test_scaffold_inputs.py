"""create-description: names that cannot become files and outputs that are no folder are refused up front."""

import os
from pathlib import Path

import pytest

from plem.description.problems import DescriptionError
from plem.description.scaffold import MAX_NAME_LENGTH, create_package, plan_package


def test_longest_name_fits_and_one_more_is_refused(tmp_path: Path):
    assert MAX_NAME_LENGTH == 222
    create_package(tmp_path, "a" * MAX_NAME_LENGTH, 6)
    with pytest.raises(DescriptionError, match=f"at most {MAX_NAME_LENGTH} fit"):
        plan_package("a" * (MAX_NAME_LENGTH + 1), 6)


def test_output_that_is_a_file_is_refused(tmp_path: Path):
    (tmp_path / "file").write_text("")
    with pytest.raises(DescriptionError, match="Not a folder"):
        create_package(tmp_path / "file", "bot", 6)


def test_output_that_cannot_be_written_is_refused():
    with pytest.raises(DescriptionError, match="Cannot write the package"):
        create_package(Path("/proc/1"), "bot", 6)


def test_a_fifo_in_the_package_differs_and_is_never_read(tmp_path: Path):
    root = create_package(tmp_path, "bot", 6).root
    (root / "package.xml").unlink()
    os.mkfifo(root / "package.xml")
    with pytest.raises(DescriptionError, match="package.xml"):
        create_package(tmp_path, "bot", 6)
    assert create_package(tmp_path, "bot", 6, force=True).overwritten == ["package.xml"]
