import json
from pathlib import Path

from tests.e2e.cli import run_plem

OFFSETS = "-535768,195386,191634,34542,24035,21232"


def test_create_show_list(isolated_environment: Path):
    created = run_plem("profile", "create", "--serial", "PE07I7E0E001", "--offsets", OFFSETS, "--dof", "6")
    assert created.returncode == 0, created.stderr
    path = isolated_environment / "profiles" / "PE07I7E0E001.json"
    stored = json.loads(path.read_text())
    assert stored["joint_offsets"][0] == -535768 and stored["profile_date"].endswith("Z")
    shown = run_plem("profile", "show", "PE07I7E0E001", "--format", "json")
    assert json.loads(shown.stdout)["joint_offsets"] == stored["joint_offsets"]
    (isolated_environment / "profiles" / "BROKEN.json").write_text("{oops")
    listed = run_plem("profile", "list")
    assert listed.returncode == 0
    assert "PE07I7E0E001" in listed.stdout and "BROKEN" in listed.stdout and "invalid" in listed.stdout


def test_existing_calibration_is_not_overwritten_without_force(isolated_environment: Path):
    assert run_plem("profile", "create", "--serial", "A1", "--offsets", "1,2,3,4,5,6").returncode == 0
    again = run_plem("profile", "create", "--serial", "A1", "--offsets", "9,9,9,9,9,9")
    assert again.returncode == 1 and "--force" in again.stderr
    forced = run_plem("profile", "create", "--serial", "A1", "--offsets", "9,9,9,9,9,9", "--force")
    assert forced.returncode == 0
    assert json.loads((isolated_environment / "profiles" / "A1.json").read_text())["joint_offsets"] == [9] * 6


def test_bad_inputs(isolated_environment: Path):
    wrong_count = run_plem("profile", "create", "--serial", "A1", "--offsets", "1,2,3", "--dof", "6")
    assert wrong_count.returncode == 1 and "joint_offsets must have exactly 6 elements" in wrong_count.stderr
    bad_serial = run_plem("profile", "create", "--serial", "../x", "--offsets", "1,2,3,4,5,6")
    assert bad_serial.returncode == 1 and "Invalid robot serial" in bad_serial.stderr
    not_numbers = run_plem("profile", "create", "--serial", "A1", "--offsets", "a,b")
    assert not_numbers.returncode == 2
    missing = run_plem("profile", "show", "NOPE")
    assert missing.returncode == 1 and "Failed to open profile file" in missing.stderr
    assert not (isolated_environment / "profiles" / "A1.json").exists()
    for result in (wrong_count, bad_serial, not_numbers, missing):
        assert "Traceback" not in result.stderr


def test_replacing_the_offsets_keeps_the_payload_and_show_prints_it(isolated_environment: Path):
    assert run_plem("profile", "create", "--serial", "A1", "--offsets", "1,2,3,4,5,6").returncode == 0
    path = isolated_environment / "profiles" / "A1.json"
    stored = json.loads(path.read_text())
    stored["payload"] = {"mass": 1.5, "center_of_mass": [0.0, 0.0, 0.05]}
    path.write_text(json.dumps(stored))
    shown = run_plem("profile", "show", "A1")
    assert "payload:       1.5 kg at [0.0, 0.0, 0.05] m in the flange frame" in shown.stdout, shown.stdout
    forced = run_plem("profile", "create", "--serial", "A1", "--offsets", "9,9,9,9,9,9", "--force")
    assert forced.returncode == 0, forced.stderr
    replaced = json.loads(path.read_text())
    assert replaced["joint_offsets"] == [9] * 6 and replaced["payload"] == stored["payload"]
    assert run_plem("profile", "create", "--serial", "B1", "--offsets", "1,2,3,4,5,6").returncode == 0
    assert "payload:       (none)" in run_plem("profile", "show", "B1").stdout
