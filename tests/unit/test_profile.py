import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plem.errors import ProfileError
from plem.robot import RobotProfile

SERIAL = "PE07I7E0E001"
OFFSETS = [-535768, 195386, 191634, 34542, 24035, 21232]


def test_default_locations(isolated_environment: Path):
    assert RobotProfile.default_directory() == isolated_environment / "profiles"
    assert RobotProfile.default_path(SERIAL) == isolated_environment / "profiles" / f"{SERIAL}.json"


def test_save_and_load_from_serial():
    profile = RobotProfile(robot_serial=SERIAL, joint_offsets=OFFSETS, profile_date="2026-02-02T12:00:00Z")
    assert profile.is_valid()
    profile.save(RobotProfile.default_path(SERIAL))
    loaded = RobotProfile.load_from_serial(SERIAL)
    assert loaded == profile
    assert oct(RobotProfile.default_path(SERIAL).stat().st_mode & 0o777) == "0o600"


def test_calibration_date_migrates(tmp_path: Path):
    path = tmp_path / "OLD001.json"
    path.write_text(json.dumps({"robot_serial": "OLD001", "joint_offsets": [1, 2, 3, 4, 5, 6],
                                "calibration_date": "2025-01-01T00:00:00Z"}))
    assert RobotProfile.load(path).profile_date == "2025-01-01T00:00:00Z"


def test_missing_file_message_names_path_and_fix(tmp_path: Path):
    with pytest.raises(ProfileError) as error:
        RobotProfile.load(tmp_path / "X1.json")
    assert error.value.summary == f"Failed to open profile file: {tmp_path / 'X1.json'}"
    assert "plem profile create --serial X1" in error.value.how


@pytest.mark.parametrize("content, fragment", [
    ("{not json", ":1:2"),
    ("[1, 2]", "JSON list"),
    ('{"robot_serial": "A1"}', "missing required field 'joint_offsets'"),
    ('{"robot_serial": "A1", "joint_offsets": [1, 2, "x", 4, 5, 6]}', "joint_offsets.2"),
    ('{"robot_serial": "A1", "joint_offsets": [1, 2, 3]}', "6 or 7"),
    ('{"robot_serial": "A1", "joint_offsets": [1, 2, 3, 4, 5, 6], "profile_date": "yesterday"}', "ISO 8601"),
    ('{"robot_serial": "../A1", "joint_offsets": [1, 2, 3, 4, 5, 6]}', "'..'"),
])
def test_bad_files_are_profile_errors(tmp_path: Path, content: str, fragment: str):
    path = tmp_path / "A1.json"
    path.write_text(content)
    with pytest.raises(ProfileError) as error:
        RobotProfile.load(path)
    assert fragment in error.value.render()


def test_profile_for_another_serial_is_refused():
    RobotProfile(robot_serial="B2", joint_offsets=[0] * 6).save(RobotProfile.default_path("A1"))
    with pytest.raises(ProfileError, match="belongs to another robot"):
        RobotProfile.load_from_serial("A1")


@pytest.mark.parametrize("serial", ["../x", "a/b", "", "..", "x" * 200])
def test_unsafe_serials_are_refused(serial):
    with pytest.raises(ProfileError):
        RobotProfile.default_path(serial)


def test_invalid_profile_is_not_saved(tmp_path: Path):
    with pytest.raises(ProfileError, match="Refusing to save"):
        RobotProfile(robot_serial="A1", joint_offsets=[1, 2]).save(tmp_path / "A1.json")
    assert not (tmp_path / "A1.json").exists()


def test_interrupted_save_leaves_the_old_file(tmp_path: Path):
    """A process killed in the middle of saving never leaves a torn file behind."""
    path = tmp_path / "A1.json"
    RobotProfile(robot_serial="A1", joint_offsets=[1] * 6).save(path)
    script = textwrap.dedent(f"""
        import os, plem.core.files as files
        real_replace = os.replace
        def crash(*args):
            os._exit(9)  # die after the temp file is written, before the rename
        os.replace = crash
        from plem.robot import RobotProfile
        RobotProfile(robot_serial="A1", joint_offsets=[2] * 6).save({str(path)!r})
    """)
    result = subprocess.run([sys.executable, "-c", script])
    assert result.returncode == 9
    assert RobotProfile.load(path).joint_offsets == [1] * 6
    leftovers = [p for p in os.listdir(tmp_path) if p != "A1.json"]
    assert leftovers  # the orphaned temp file is harmless and never read as the profile
    assert all(name.startswith(".A1.json.") for name in leftovers)


serials = st.from_regex(r"[A-Za-z0-9][A-Za-z0-9_-]{0,30}", fullmatch=True)
offsets = st.integers(min_value=-(2**31), max_value=2**31 - 1)


@settings(max_examples=100, deadline=None)
@given(serial=serials, dof=st.sampled_from([6, 7]), data=st.data(),
       date=st.one_of(st.none(), st.datetimes().map(lambda d: d.replace(microsecond=0).isoformat())))
def test_round_trip_preserves_every_field(tmp_path_factory, serial, dof, data, date):
    values = data.draw(st.lists(offsets, min_size=dof, max_size=dof))
    profile = RobotProfile(robot_serial=serial, joint_offsets=values, profile_date=date)
    path = tmp_path_factory.mktemp("rt") / f"{serial}.json"
    profile.save(path)
    assert RobotProfile.load(path) == profile


@settings(max_examples=200, deadline=None)
@given(content=st.one_of(st.text(), st.binary().map(lambda b: b.decode("latin-1")),
                         st.recursive(st.none() | st.booleans() | st.integers() | st.text(),
                                      lambda inner: st.lists(inner) | st.dictionaries(st.text(), inner))
                         .map(json.dumps)))
def test_garbage_files_only_ever_raise_profile_errors(tmp_path_factory, content):
    path = tmp_path_factory.mktemp("garbage") / "G1.json"
    path.write_text(content, encoding="utf-8", errors="surrogatepass")
    try:
        profile = RobotProfile.load(path)
    except ProfileError as error:
        assert error.render().startswith("ERROR: ")
    else:
        assert profile.is_valid()
