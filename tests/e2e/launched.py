"""Robots brought up with the real `plem launch`, watched through what it prints and what it leaves in /dev/shm."""

from __future__ import annotations

import contextlib
import os
import pwd
import re
import select
import shutil
import signal
import subprocess
import sys
import sysconfig
import textwrap
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import plem
from plem.ipc.robot_description import description_path
from plem.ipc.segment import SHM_DIRECTORY
from plem.launch.startup import LIMIT_S
from plem.recording.status import status_path
from tests.conftest import ISOLATED_PREFIXES, TEST_DOMAIN_ID, fresh_domain
from tests.e2e.cli import plem_executable

READY_LINE = "Ctrl-C stops the arm"
#: How long a launch may say nothing new before a wait for its output fails.
READY_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 30.0
_DRIVER_LINE = re.compile(r"^robot (\S+) \(.*\n\s+rt_driver\s+running, pid (\d+)", re.MULTILINE)
_GENERATED = re.compile(r"Generated files are in (\S+);")


def new_robot_id() -> str:
    return f"e2e_{uuid.uuid4().hex[:8]}"


def clean_environment(home: Path, **extra: str) -> dict[str, str]:
    """The caller's environment without plem/ROS variables, with a private PLEM_HOME and HOME (bags go to
    ~/bags/rt_monitoring by default); DDS stays on this host."""
    env = {name: value for name, value in os.environ.items() if not name.startswith(ISOLATED_PREFIXES)}
    return {**env, "PLEM_HOME": str(home), "HOME": str(home), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "ROS_DOMAIN_ID": str(TEST_DOMAIN_ID), **extra}


def shm_files(robot_id: str) -> list[Path]:
    """Every /dev/shm file of a robot (they all start with its robot_id)."""
    return sorted(SHM_DIRECTORY.glob(f"{robot_id}_*"))


def remove_shm(robot_id: str) -> None:
    for path in shm_files(robot_id):
        path.unlink(missing_ok=True)
    status_path(robot_id).unlink(missing_ok=True)          # left only by a killed recorder
    description_path(robot_id).unlink(missing_ok=True)     # left only by a killed launch


def remove_generated(output: str) -> None:
    """Delete the temp directories a launch generated description files into (it names them)."""
    for directory in _GENERATED.findall(output):
        if Path(directory).name.startswith("wim_launch_"):
            shutil.rmtree(directory, ignore_errors=True)


def process_gone(pid: int) -> bool:
    """True when `pid` no longer runs (no such process, or a zombie waiting for its parent)."""
    try:
        status = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return True
    return status.rsplit(")", 1)[1].split()[0] in ("Z", "X")


def process_reaped(pid: int) -> bool:
    """True when `pid` is gone entirely, not even a zombie (its owner check in plem counts zombies as alive)."""
    return not Path(f"/proc/{pid}").exists()


def wait_for(produce: Callable[[], Any], timeout: float, period: float = 0.01) -> Any:
    """The first truthy value `produce` returns within `timeout`, else None."""
    deadline = time.monotonic() + timeout
    while True:
        value = produce()
        if value:
            return value
        if time.monotonic() > deadline:
            return None
        time.sleep(period)


def ros_environment(home: Path, domain: int | None = None) -> dict[str, str]:
    """A launch environment on a domain of its own, discovery on this host only."""
    domain = fresh_domain() if domain is None else domain
    return clean_environment(home, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(domain))


def wait_until(condition, timeout: float, period: float = 0.02) -> bool:
    deadline = time.monotonic() + timeout
    while True:
        if condition():
            return True
        if time.monotonic() > deadline:
            return False
        time.sleep(period)


class Launch:
    """One running `plem launch` with its stdout and stderr in files."""

    def __init__(self, arguments: Sequence[str], robot_ids: Sequence[str], directory: Path,
                 env: dict[str, str], command_prefix: Sequence[str] = ()) -> None:
        # Without planner:= the planner stays off: it costs a second of CPU per launch, and only the planning
        # tests (which pass planner:=true) use it.
        planner = [] if any(argument.startswith("planner:=") for argument in arguments) else ["planner:=false"]
        self.arguments = [*arguments, *planner]
        self.robot_ids = list(robot_ids)
        self.env = env
        directory.mkdir(parents=True, exist_ok=True)
        tag = uuid.uuid4().hex[:6]
        self.stdout_path = directory / f"launch_{tag}.out"
        self.stderr_path = directory / f"launch_{tag}.err"
        with open(self.stdout_path, "w") as out, open(self.stderr_path, "w") as err:
            self.process = subprocess.Popen([*command_prefix, plem_executable(), "launch", *self.arguments],
                                            stdin=subprocess.DEVNULL, stdout=out, stderr=err, env=env)

    @property
    def robot_id(self) -> str:
        return self.robot_ids[0]

    @property
    def output(self) -> str:
        return self.stdout_path.read_text()

    @property
    def errors(self) -> str:
        return self.stderr_path.read_text()

    def describe(self) -> str:
        return f"plem launch {' '.join(self.arguments)}\n--- stdout\n{self.output}\n--- stderr\n{self.errors}"

    def wait_for(self, text: str, timeout: float = READY_TIMEOUT_S) -> None:
        """Block until `text` appears on stdout; fails if the launch exits first, or says nothing new for `timeout`
        (a launch slowed by a busy machine keeps saying how far it got, so the wait follows it, up to `LIMIT_S`)."""
        started = time.monotonic()
        seen, quiet_since = "", started
        while text not in (output := self.output):
            now = time.monotonic()
            if output != seen:
                seen, quiet_since = output, now
            if self.process.poll() is not None and text not in self.output:
                raise AssertionError(f"launch exited with {self.process.returncode} before {text!r}\n"
                                     + self.describe())
            if now - quiet_since > timeout or now - started > LIMIT_S:
                raise AssertionError(f"no {text!r} after {now - started:.0f} s, {now - quiet_since:.0f} s of them "
                                     "without output\n" + self.describe())
            time.sleep(0.05)

    def driver_pids(self) -> dict[str, int]:
        """The RT driver pid of each robot, as the summary reports it."""
        return {robot_id: int(pid) for robot_id, pid in _DRIVER_LINE.findall(self.output)}

    def component_pid(self, component: str) -> int:
        """The pid of a component (bridge, recorder) of a one-robot launch, as the summary reports it."""
        found = re.search(rf"^\s+{component}\s+\w+, pid (\d+)", self.output, re.MULTILINE)
        assert found, f"no running {component} in\n{self.describe()}"
        return int(found.group(1))

    def stop(self) -> int:
        """Ctrl-C, as a user would; kills the launch and its drivers if they do not stop in time."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        for pid in self.driver_pids().values():
            if not process_gone(pid):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
                wait_until(lambda pid=pid: process_gone(pid), 10)
        return self.process.returncode

    def cleanup(self) -> None:
        self.stop()
        remove_generated(self.output)
        for robot_id in self.robot_ids:
            remove_shm(robot_id)


def start_launch(arguments: Sequence[str], robot_ids: Sequence[str], directory: Path, env: dict[str, str],
                 *, ready: bool = True) -> Launch:
    launch = Launch(arguments, robot_ids, directory, env)
    if ready:
        try:
            launch.wait_for(READY_LINE)
        except BaseException:
            launch.cleanup()
            raise
    return launch


@contextlib.contextmanager
def launched(arguments: Sequence[str], robot_ids: Sequence[str], directory: Path,
             env: dict[str, str]) -> Iterator[Launch]:
    """A launch that reached its summary; stopped with Ctrl-C and cleaned up afterwards."""
    launch = start_launch(arguments, robot_ids, directory, env)
    try:
        yield launch
    finally:
        launch.cleanup()


@contextlib.contextmanager
def launched_robot(tmp_path_factory: Any, *arguments: str, ros: bool = False) -> Iterator[Launch]:
    """One simulated arm launched with `arguments` for a module's tests, in a temp folder of its own; with `ros`,
    on a DDS domain of its own (see `ros_environment` and `join_domain`)."""
    directory = tmp_path_factory.mktemp("launch")
    robot_id = new_robot_id()
    environment = (ros_environment if ros else clean_environment)(directory / "plem_home")
    with launched(["bus:=mock", f"robot_id:={robot_id}", *arguments], [robot_id], directory, environment) as launch:
        yield launch


def join_domain(monkeypatch: Any, launch: Launch) -> None:
    """This process joins the launch's DDS domain, as a ROS 2 user's shell would."""
    for name in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID"):
        monkeypatch.setenv(name, launch.env[name])


def system_python() -> str | None:
    """An interpreter of the tests' Python version outside root's home, which other users can run."""
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    return next((str(path) for path in (Path("/usr/bin") / version, Path("/usr/local/bin") / version)
                 if path.exists()), None)


def as_nobody(code: str, *args: str, groups: Sequence[int] = ()) -> subprocess.Popen:
    """`code` (dedented) as user nobody under the system interpreter, with plem importable; stdout piped, text.

    Needs root and `system_python()`; the caller skips without them.
    """
    nobody = pwd.getpwnam("nobody")
    path = os.pathsep.join([str(Path(plem.__file__).parents[1]), sysconfig.get_paths()["purelib"]])
    return subprocess.Popen([system_python() or "python3", "-c", textwrap.dedent(code), *args], user=nobody.pw_uid,
                            group=nobody.pw_gid, extra_groups=list(groups), cwd="/", stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={"PATH": "/usr/bin:/bin", "PYTHONPATH": path, "HOME": "/tmp"})


def python_client(code: str, *args: str, env: dict[str, str] | None = None) -> subprocess.Popen:
    """Another process running `code` (dedented) with `args` in sys.argv[1:]; stdout piped, text mode."""
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code), *args], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def read_line(process: subprocess.Popen, timeout: float) -> str:
    """The next stdout line of `process`, or '' when it ended or said nothing within `timeout`.

    The pipe is read a byte at a time: a buffered readline may take the next line into its buffer too, where
    select no longer sees it, and the next call would wait for a line that has already arrived.
    """
    fd = process.stdout.fileno()
    deadline = time.monotonic() + timeout
    line = bytearray()
    while not line.endswith(b"\n"):
        remaining = deadline - time.monotonic()
        if remaining <= 0 or not select.select([fd], [], [], remaining)[0]:
            return ""
        byte = os.read(fd, 1)
        if not byte:
            break
        line += byte
    return line.decode()
