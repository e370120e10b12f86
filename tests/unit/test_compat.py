"""PLEM_COMPAT_VERSION: versions no int should be made of, and files that are no regular file."""

import os
from pathlib import Path

import pytest

from plem.description.compat import check_compat_version
from plem.description.problems import Findings


def check(tmp_path: Path, make) -> Findings:
    path = tmp_path / "PLEM_COMPAT_VERSION"
    make(path)
    found = Findings()
    check_compat_version(path, tmp_path, found)
    return found


@pytest.mark.parametrize(("make", "code", "fragment"), [
    (lambda path: path.write_text("1." + "7" * 5000 + ".0\n"), "compat.semver", "(5004 characters)"),
    (lambda path: path.write_text("1.1234567890.0\n"), "compat.semver", "'1.1234567890.0'"),
    (lambda path: path.write_text("1" * 70_000), "compat.unreadable", "holds 68.4 KiB"),
    (lambda path: os.mkfifo(path), "compat.unreadable", "is a FIFO"),
])
def test_bad_versions_are_errors(tmp_path: Path, make, code: str, fragment: str):
    found = check(tmp_path, make)
    assert found.codes() == [code] and fragment in found.errors[0].why


def test_nine_digit_parts_are_still_versions(tmp_path: Path):
    assert check(tmp_path, lambda path: path.write_text("1.123456789.0\n")).codes() == ["compat.minor_newer"]
