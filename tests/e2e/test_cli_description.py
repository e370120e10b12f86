import json
import os
import pty
import select
import shlex
import subprocess
from pathlib import Path

from tests.e2e.cli import plem_executable, run_plem
from tests.integration.packages import copy_builtin


def test_validate_builtin_by_name():
    result = run_plem("validate", "indy7_v2_description", "--strict")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("OK: indy7_v2_description") and "DOF 6 [strict]" in result.stdout


def test_validate_reports_all_errors_and_exits_1(tmp_path: Path):
    package = copy_builtin("indy7", tmp_path)
    (package / "PLEM_COMPAT_VERSION").write_text("2.0.0\n")
    limits = package / "config" / "joint_limits.yaml"
    limits.write_text(limits.read_text().replace("joint3:", "joint9:"))
    result = run_plem("validate", str(package))
    assert result.returncode == 1
    assert result.stderr.count("ERROR:") == 3  # major version, missing joint3, extra joint9
    assert f"{limits}:" in result.stderr and "Traceback" not in result.stderr
    assert "FAILED: indy7_description" in result.stdout


def test_warnings_pass_unless_strict_and_json_lists_them(tmp_path: Path):
    package = copy_builtin("indy7", tmp_path)
    (package / "PLEM_COMPAT_VERSION").write_text("1.9.0\n")
    assert run_plem("validate", str(package)).returncode == 0
    strict = run_plem("validate", str(package), "--strict", "--format", "json")
    assert strict.returncode == 1
    data = json.loads(strict.stdout)
    assert data["passed"] is False and data["errors"] == []
    assert [w["code"] for w in data["warnings"]] == ["compat.minor_newer"]
    assert data["warnings"][0]["line"] == 1


def test_validate_usage_errors():
    assert run_plem("validate").returncode == 2
    missing = run_plem("validate", "./no/such/dir")
    assert missing.returncode == 1 and "Package directory not found" in missing.stderr


def test_create_description_without_terminal_names_the_missing_flags(tmp_path: Path):
    result = subprocess.run([plem_executable(), "create-description", "--dof", "6", "--output", str(tmp_path)],
                            stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "Missing --name" in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_create_description_then_validate(tmp_path: Path):
    created = run_plem("create-description", "--name", "cell_arm", "--dof", "7", "--with-moveit",
                       "--output", str(tmp_path))
    assert created.returncode == 0, created.stderr
    assert "created            srdf/cell_arm.srdf" in created.stdout
    again = run_plem("create-description", "--name", "cell_arm", "--dof", "7", "--with-moveit",
                     "--output", str(tmp_path))
    assert "identical, skipped" in again.stdout and "created " not in again.stdout
    assert run_plem("validate", str(tmp_path / "cell_arm_description"), "--strict").returncode == 0


def _run_on_terminal(args: list[str], answers: list[str], cwd: Path) -> tuple[int, str]:
    """Run plem with a pseudo-terminal as stdin/stdout, typing `answers` at its prompts."""
    controller, terminal = pty.openpty()
    process = subprocess.Popen([plem_executable(), *args], stdin=terminal, stdout=terminal, stderr=terminal,
                               cwd=cwd, env={**os.environ, "TERM": "dumb"})
    os.close(terminal)
    output, pending = b"", list(answers)
    while True:
        ready, _, _ = select.select([controller], [], [], 30)
        if not ready:
            process.kill()
            break
        try:
            chunk = os.read(controller, 4096)
        except OSError:
            break
        if not chunk:
            break
        output += chunk
        if pending and output.rstrip().endswith((b":", b"]", b")")):
            os.write(controller, pending.pop(0).encode() + b"\n")
    os.close(controller)
    return process.wait(timeout=30), output.decode(errors="replace")


def test_create_description_asks_on_a_terminal(tmp_path: Path):
    code, output = _run_on_terminal(["create-description"], ["term_arm", "7", "y", "n"], tmp_path)
    assert code == 0, output
    root = tmp_path / "term_arm_description"
    assert (root / "srdf" / "term_arm.srdf").is_file() and not (root / "launch").exists()
    assert "Robot name" in output and "Number of joints" in output


def test_create_description_prints_a_next_command_that_works(tmp_path: Path):
    """The "Next:" line, run as printed in the folder create-description ran in, validates the new package."""
    created = subprocess.run([plem_executable(), "create-description", "--name", "my_robot", "--dof", "6"],
                             capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert created.returncode == 0, created.stderr
    (command,) = [line.removeprefix("Next: ") for line in created.stdout.splitlines() if line.startswith("Next: ")]
    assert command == "plem validate ./my_robot_description --strict"
    program, *arguments = shlex.split(command)
    validated = subprocess.run([plem_executable(), *arguments], capture_output=True, text=True, cwd=tmp_path,
                               timeout=120)
    assert program == "plem" and validated.returncode == 0, validated.stdout + validated.stderr
