"""Description packages are untrusted input: rendering one runs no code, reads nothing outside packages, leaks no
environment, runs without root and within limits, and a package name never resolves to the working directory."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
import xacro

from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.description.discover import locate_package, package_for_launch
from plem.description.render import render_xacro
from plem.description.sandbox import NOBODY, SandboxError, run_sandboxed
from plem.description.validate import validate_package
from plem.errors import PackageNotFoundError, PlemError
from plem.fieldbus.mock import MockBus
from plem.robot import Indy7V2, Robot
from tests.e2e.cli import plem_executable
from tests.e2e.launched import as_nobody, system_python
from tests.integration.packages import copy_builtin
from tests.integration.robot_fixtures import RAW_ZERO

BUILTIN = "indy7_v2_description"
SECRET = "plem-test-secret-7f3a"
needs_root = pytest.mark.skipif(os.geteuid() != 0, reason="dropping privileges can only be checked when run as root")

# Reaches os.system with xacro's own exposed helpers (python.type, python.vars), no dunder name in the code.
ESCAPE = """
  <xacro:property name="T" value="${python.type}"/>
  <xacro:property name="V" value="${python.vars}"/>
  <xacro:property name="subs" value="${V(T)['__subclasses__'](T('').mro()[1])}"/>
  <xacro:property name="wc" value="${list(python.filter(lambda c, R=python.repr: 'wrap_close' in R(c), subs))[0]}"/>
  <xacro:property name="init" value="${V(wc)['__init__']}"/>
  <xacro:property name="gd" value="${V(T(init))['__globals__']}"/>
  <xacro:property name="os" value="${V(T(gd))['__get__'](gd, init)}"/>
"""


def xacro_file(folder: Path, body: str, package: str = "hostile_description") -> Path:
    """`folder/package/urdf/robot.urdf.xacro` holding `body` inside <robot>, in a package with package.xml."""
    root = folder / package
    (root / "urdf").mkdir(parents=True, exist_ok=True)
    (root / "package.xml").write_text(f"<package><name>{package}</name></package>", encoding="utf-8")
    path = root / "urdf" / "robot.urdf.xacro"
    path.write_text(f'<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r">{body}</robot>', encoding="utf-8")
    return path


def refused(path: Path) -> PlemError:
    """The PlemError rendering `path` raises (failing the test if it renders)."""
    with pytest.raises(PlemError) as error:
        render_xacro(path)
    return error.value


@pytest.fixture
def shared_dir() -> Iterator[Path]:
    """A world-writable folder that every user can reach (unlike pytest's private tmp_path)."""
    path = Path(tempfile.mkdtemp(prefix="plem-hostile-", dir="/tmp"))
    path.chmod(0o1777)
    yield path
    shutil.rmtree(path)


# -- 1: expressions run no code ----------------------------------------------------------------------------------

def test_expression_escape_to_os_system_is_refused(tmp_path: Path):
    marker = tmp_path / "pwned"
    path = xacro_file(tmp_path, ESCAPE + f"""<link name="${{os['system']('touch {marker}')}}"/>""")
    refused(path)
    assert not marker.exists()


def test_str_format_cannot_read_internals(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("PLEM_TEST_SECRET", SECRET)
    path = xacro_file(tmp_path, """<xacro:property name="f" value="{0.__globals__[os].environ}"/>
                                   <link name="${f.format(xacro.arg)}"/>""")
    error = refused(path)
    assert "format" in error.summary and SECRET not in error.render()


def test_generator_frames_are_out_of_reach(tmp_path: Path):
    path = xacro_file(tmp_path, """<link name="${[g.gi_frame for g in [(x for x in [1])]]}"/>""")
    assert "gi_frame" in refused(path).summary


def test_eval_substitution_has_no_open(tmp_path: Path):
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET, encoding="utf-8")
    path = xacro_file(tmp_path, f"""<xacro:property name="code" value="open('{secret}').read()"/>
                                    <link name="$(eval ${{code}})"/>""")
    error = refused(path)
    assert "open" in error.why and SECRET not in error.render()


def test_legitimate_expressions_still_work(tmp_path: Path):
    path = xacro_file(tmp_path, """<xacro:property name="table" value="${dict(a=[1, 2, 3])}"/>
        <link name="${'%.3f' % (pi / 2)}_${radians(180) == pi}_${table['a'][2]}_${cos(0)}_$(eval 2 * 3)"/>""")
    assert '<link name="1.571_True_3_1.0_6"/>' in render_xacro(path)


# -- nothing runs as root -----------------------------------------------------------------------------------------

@needs_root
def test_render_runs_as_nobody_for_a_root_owned_package(tmp_path: Path, shared_dir: Path,
                                                        monkeypatch: pytest.MonkeyPatch):
    """Even with the expression checks taken away, the escape runs as nobody: it can create a file only where
    anyone may, and never one owned by root."""
    monkeypatch.setattr(xacro, "safe_eval", _unchecked_eval)
    monkeypatch.setitem(xacro._global_symbols["python"], "type", type)
    monkeypatch.setitem(xacro._global_symbols["python"], "vars", vars)
    open_anywhere = shared_dir / "created_by_escape"
    root_only = shared_dir / "root_only"
    root_only.mkdir(mode=0o755)
    path = xacro_file(tmp_path, ESCAPE + f"""
        <link name="${{os['open']('{open_anywhere}', 0o101)}}"/>
        <link name="${{os['system']('touch {root_only / 'file'}')}}"/>""")
    render_xacro(path)
    assert open_anywhere.stat().st_uid == NOBODY
    assert not (root_only / "file").exists()


def _unchecked_eval(expression, symbols, local_symbols=None):
    """xacro's own evaluation, without plem's checks."""
    symbols.update(__builtins__={})
    return eval(expression.strip(), symbols, local_symbols)  # unchecked on purpose


def _identity() -> str:
    return json.dumps([os.getresuid(), os.getresgid(), os.getgroups()])


@needs_root
def test_child_takes_the_package_owners_ids(tmp_path: Path):
    owned = tmp_path / "owned"
    owned.mkdir()
    os.chown(owned, 4321, 4322)
    uids, gids, groups = json.loads(run_sandboxed(_identity, task="checking ids", owner=owned))
    assert (uids, gids, groups) == ([4321] * 3, [4322] * 3, [])
    uids, gids, groups = json.loads(run_sandboxed(_identity, task="checking ids", owner=tmp_path))
    assert (uids, gids, groups) == ([NOBODY] * 3, [NOBODY] * 3, [])


def _spawn() -> str:
    return str(os.system("true"))


def test_child_cannot_start_processes(tmp_path: Path):
    assert run_sandboxed(_spawn, task="spawning", owner=tmp_path) != "0"


# -- 2: a package name never resolves to the working directory ------------------------------------------------------

@pytest.fixture
def planted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A working directory holding a broken folder named like the built-in package, as another user could plant."""
    fake = copy_builtin("indy7_v2", tmp_path)
    (fake / "config" / "joint_limits.yaml").write_text("planted: [", encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    return fake


def test_validate_by_name_uses_the_builtin_not_the_working_directory(planted: Path):
    report = validate_package(BUILTIN)
    assert report.files.root == BUILTIN_PACKAGES_DIR / BUILTIN and report.passed()
    assert validate_package("./" + BUILTIN).files.root == planted  # a path still reaches it


def test_cli_validate_by_name_uses_the_builtin(planted: Path):
    done = subprocess.run([plem_executable(), "validate", BUILTIN, "--format", "json"], cwd=planted.parent,
                          check=False, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["path"] == str(BUILTIN_PACKAGES_DIR / BUILTIN)


def test_launch_and_builder_resolve_the_builtin(planted: Path):
    assert locate_package(package_for_launch(BUILTIN, None)) == BUILTIN_PACKAGES_DIR / BUILTIN
    config = Indy7V2()
    config.joint_offsets = [-r for r in RAW_ZERO]
    robot = Robot.builder(config).with_bus(MockBus(config.dof, raw_zero=RAW_ZERO)).with_description(BUILTIN).build()
    robot.shutdown()


def test_name_only_in_working_directory_suggests_a_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    copy_builtin("indy7_v2", tmp_path).rename(tmp_path / "cell_description")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(PackageNotFoundError) as error:
        locate_package("cell_description")
    assert "did you mean ./cell_description?" in error.value.how
    assert locate_package("./cell_description") == tmp_path / "cell_description"


# -- 3: only package files are read, no environment is copied ------------------------------------------------------

@pytest.mark.parametrize("target", ["/etc/passwd", "outside"])
def test_load_yaml_outside_packages_is_refused(tmp_path: Path, target: str):
    outside = tmp_path / "outside.yaml"
    outside.write_text(f"secret: {SECRET}\n", encoding="utf-8")
    name = str(outside) if target == "outside" else target
    path = xacro_file(tmp_path, f"""<link name="${{xacro.load_yaml('{name}')}}"/>""")
    error = refused(path)
    assert "not allowed" in error.summary and SECRET not in error.render()


def test_include_and_find_outside_packages_are_refused(tmp_path: Path):
    (tmp_path / "outside.xacro").write_text(f'<robot><link name="{SECRET}"/></robot>', encoding="utf-8")
    path = xacro_file(tmp_path, '<xacro:include filename="$(find hostile_description)/../outside.xacro"/>')
    assert "not allowed" in refused(path).summary


def test_symbolic_link_out_of_the_package_is_refused(tmp_path: Path):
    outside = tmp_path / "outside.yaml"
    outside.write_text(f"secret: {SECRET}\n", encoding="utf-8")
    path = xacro_file(tmp_path, """<link name="${xacro.load_yaml('limits.yaml')['secret']}"/>""")
    (path.parent / "limits.yaml").symlink_to(outside)
    error = refused(path)
    assert "link" in error.why and SECRET not in error.render()


def test_package_files_are_read(tmp_path: Path):
    path = xacro_file(tmp_path, """<link name="${xacro.load_yaml('$(find hostile_description)/config/l.yaml').a}"/>
                                   <xacro:include filename="part.xacro"/>""")
    (path.parents[1] / "config").mkdir()
    (path.parents[1] / "config" / "l.yaml").write_text("a: from_yaml\n", encoding="utf-8")
    (path.parent / "part.xacro").write_text('<robot><link name="included"/></robot>', encoding="utf-8")
    xml = render_xacro(path)
    assert '<link name="from_yaml"/>' in xml and '<link name="included"/>' in xml


def test_env_is_refused_and_optenv_gives_its_default(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("PLEM_TEST_SECRET", SECRET)
    error = refused(xacro_file(tmp_path, '<link name="$(env PLEM_TEST_SECRET)"/>'))
    assert "$(env PLEM_TEST_SECRET)" in error.summary and SECRET not in error.render()
    xml = render_xacro(xacro_file(tmp_path, '<link name="$(optenv PLEM_TEST_SECRET fallback)"/>', "other_description"))
    assert '<link name="fallback"/>' in xml and SECRET not in xml


# -- limits -----------------------------------------------------------------------------------------------------------

def limit_error(path: Path) -> SandboxError:
    with pytest.raises(SandboxError) as error:
        render_xacro(path)
    return error.value


def test_memory_limit(tmp_path: Path):
    error = limit_error(xacro_file(tmp_path, """<link name="${'x' * 2**33}"/>"""))
    assert "memory limit" in error.summary and "PLEM_RENDER_MEMORY_MB" in error.how


def test_output_limit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("PLEM_RENDER_OUTPUT_MB", "1")
    error = limit_error(xacro_file(tmp_path, """<link name="${'x' * 2**21}"/>"""))
    assert "output limit" in error.summary and "PLEM_RENDER_OUTPUT_MB" in error.how


def test_cpu_limit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("PLEM_RENDER_CPU_SECONDS", "1")
    error = limit_error(xacro_file(tmp_path, """<link name="${python.sum(python.range(10**15))}"/>"""))
    assert "CPU-time limit" in error.summary and "PLEM_RENDER_CPU_SECONDS" in error.how, error.render()


def test_wall_clock_timeout(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("PLEM_RENDER_TIMEOUT_SECONDS", "1")
    error = limit_error(xacro_file(tmp_path, """<link name="${python.sum(python.range(10**15))}"/>"""))
    assert "took too long" in error.summary and "PLEM_RENDER_TIMEOUT_SECONDS" in error.how


def test_endless_macro_recursion_is_an_error(tmp_path: Path):
    path = xacro_file(tmp_path, """<xacro:macro name="again"><xacro:again/></xacro:macro><xacro:again/>""")
    assert "recursion" in refused(path).render()


def _crash() -> str:
    os.kill(os.getpid(), signal.SIGSEGV)
    return ""


def test_crash_is_reported(tmp_path: Path):
    with pytest.raises(SandboxError) as error:
        run_sandboxed(_crash, task="crashing", owner=tmp_path)
    assert "crashed" in error.value.summary and "Segmentation fault" in error.value.why


def test_cli_reports_a_limit_without_traceback(tmp_path: Path):
    package = copy_builtin("indy7_v2", tmp_path)
    urdf = package / "urdf" / "indy7_v2.urdf.xacro"
    urdf.write_text(urdf.read_text(encoding="utf-8").replace("</robot>", """<link name="${'x' * 2**33}"/></robot>"""),
                    encoding="utf-8")
    done = subprocess.run([plem_executable(), "validate", str(package)], check=False, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 1
    assert "memory limit" in done.stderr and "Traceback" not in done.stderr + done.stdout


# -- a user other than root renders under the same rules and limits ----------------------------------------------

@pytest.mark.skipif(os.geteuid() != 0 or system_python() is None,
                    reason="acting as another user needs root and a system Python of the tests' version")
def test_a_user_other_than_root_renders_under_the_same_rules(shared_dir: Path):
    marker = shared_dir / "pwned"
    escape = xacro_file(shared_dir, ESCAPE + f"""<link name="${{os['system']('touch {marker}')}}"/>""",
                        "escape_description")
    leak = xacro_file(shared_dir, """<link name="${xacro.load_yaml('/etc/passwd')}"/>""", "leak_description")
    for path in (escape, leak):
        for folder in (path.parents[1], path.parent):
            folder.chmod(0o755)
        path.chmod(0o644)
    checker = as_nobody("""
        import sys
        from plem.description.render import render_xacro
        from plem.errors import PlemError
        for path in sys.argv[1:]:
            try:
                render_xacro(path)
                print("rendered")
            except PlemError as error:
                print("refused", error.summary)
    """, str(escape), str(leak))
    out, err = checker.communicate(timeout=120)
    lines = out.splitlines()
    assert len(lines) == 2 and all(line.startswith("refused") for line in lines), out + err
    assert "not allowed" in lines[1]
    assert not marker.exists()



@pytest.mark.skipif(os.geteuid() != 0 or system_python() is None,
                    reason="acting as another user needs root and a system Python of the tests' version")
def test_a_user_other_than_root_renders_within_the_time_limit(shared_dir: Path):
    path = xacro_file(shared_dir, """<link name="${python.sum(python.range(10**15))}"/>""", "slow_description")
    for folder in (path.parents[1], path.parent):
        folder.chmod(0o755)
    path.chmod(0o644)
    checker = as_nobody("""
        import os, sys
        os.environ["PLEM_RENDER_TIMEOUT_SECONDS"] = "1"
        from plem.description.render import render_xacro
        from plem.errors import PlemError
        try:
            render_xacro(sys.argv[1])
            print("rendered")
        except PlemError as error:
            print(error.summary, "|", error.how)
    """, str(path))
    try:
        out, err = checker.communicate(timeout=120)
    finally:
        checker.kill()  # a render without a time limit would run on
    assert "took too long" in out and "PLEM_RENDER_TIMEOUT_SECONDS" in out, out + err

def _policy() -> str:
    return str(os.sched_getscheduler(0))


@needs_root
def test_a_render_started_from_a_real_time_thread_runs_at_ordinary_priority():
    previous = os.sched_getscheduler(0), os.sched_getparam(0)
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
    try:
        policy = run_sandboxed(_policy, task="reading the policy", owner=BUILTIN_PACKAGES_DIR)
    finally:
        os.sched_setscheduler(0, previous[0], previous[1])
    assert int(policy) == os.SCHED_OTHER
