"""Every command of README.md and docs/*.md, run as the docs give it, so that the docs cannot drift from plem.

tests/docs_commands.py extracts the commands. Each is run here or listed in its NOT_RUN table with a reason:
- commands that need no arm run in a temp directory with a private PLEM_HOME, in doc order;
- commands that need an arm run, doc by doc in doc order, against one simulated arm launched with the docs'
  `plem launch bus:=mock` (plus its own robot_id, DDS domain and the planner): the docs' robot ids become
  that robot's id, `~` its home (so ~/bags/rt_monitoring is its recorder's directory), and the files a doc
  shows (`# scene.yaml`) are written beside the commands first;
- commands that run until Ctrl-C are stopped with SIGINT after their first line, which must be what the doc
  says they print;
- the other `plem launch` lines start their own arm, which must come up and stop cleanly;
- EtherCAT commands need root and are slow: `pytest -m slow`.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.docs_commands import DOCS, NOT_RUN, DocCommand, commands_of, doc_commands, doc_files, doc_name, synopsis
from tests.e2e.cli import plem_executable
from tests.e2e.launched import (
    READY_LINE,
    Launch,
    clean_environment,
    launched_robot,
    new_robot_id,
    read_line,
    ros_environment,
    start_launch,
)

COMMAND_TIMEOUT_S = 180.0       # a plan, a 3 s trajectory or a bag plot on a machine other tests keep busy
FIRST_LINE_TIMEOUT_S = 90.0
STOP_TIMEOUT_S = 30.0
BROKEN = ("Internal error", "Traceback")
#: The robot ids the docs use: each becomes the launched robot's.
DOC_ROBOT_IDS = re.compile(r"\b(indy|arm_left)\b")
#: Commands that need no arm.
OFFLINE = {"create-description", "validate", "config"}
#: Commands that need a running arm.
ON_ARM = {"state", "view", "move", "plan", "mode", "reset", "topic", "service", "action", "node", "bag", "scene",
          "speed", "jog"}
#: The launch that starts the arm the ON_ARM commands run against.
ARM_LAUNCH = "plem launch bus:=mock"

#: What a command that runs until Ctrl-C prints first, as the doc says (a regex; {robot_id} is the launched robot's).
FIRST_LINES: dict[str, str] = {
    "plem state --watch": r"^{robot_id}: \w+, cycle \d+, drives (enabled|disabled), position rad( [+-]\d+\.\d+){{6}}$",
    "plem view": r"^plem view: {robot_id} live from shared memory at http://127\.0\.0\.1:\d+ — Ctrl-C to stop",
    "plem view arm_left": r"^plem view: {robot_id} live from shared memory at http://127\.0\.0\.1:\d+",
    "plem view --ros arm_left": r"^plem view: {robot_id} live from DDS at http://127\.0\.0\.1:\d+",
    "plem topic hz /indy/rt_raw": r"^average rate: \d+\.\d+$",
    "plem topic echo /indy/robot_description": r'^data: ".*<robot name=\\"indy7_v2\\"',
    'plem topic pub /chatter std_msgs/msg/String "{data: hello}" -r 10': r"^publisher: beginning loop",
    "plem ethercat simulate robot_type:=indy7_v2": r"plemec0",
}
#: What a finite command prints, where the doc's comment says it ({robot_id} and {home} filled in).
SAYS: dict[str, str] = {
    "plem plan --to zero --dry-run": "nothing moved",
    "plem node list": "/{robot_id}/controller_manager",
    "plem topic list -t": "/{robot_id}/joint_states [sensor_msgs/msg/JointState]",
    "plem scene attach box --link tcp": "{robot_id}: box attached to tcp",
    "plem topic hz /indy/rt_raw --duration 5": "average rate:",
    "plem bag info ~/bags/rt_monitoring": "{robot_id}_",
    "plem bag plot ~/bags/rt_monitoring --out run.png": "wrote run.png",
    "plem launch --help": "robot_id:=",
}
#: What a launch of the docs prints in its summary, as the doc's arguments or comments say.
LAUNCH_SAYS: dict[str, tuple[str, ...]] = {
    ARM_LAUNCH: ("planner       running", "recording, pid", "into {home}/bags/rt_monitoring/{robot_id} "),
    "plem launch bus:=mock robot_type:=indyrp2_v2 rt_priority:=80 cycle_time:=500": ("(indyrp2_v2)", "cycle 500 µs"),
    "plem launch description_package:=./my_robot_description bus:=mock": ("(my_robot)",),
    "plem launch my_robot_description/launch/bringup.launch.py bus:=mock": ("(my_robot)",),
    "plem launch bus:=mock bag_dir:=/data/bags retention_minutes:=120 disk_threshold:=80":
        ("into {home}/data/bags/{robot_id} ", "retention 120 min, disk_threshold 80 %"),
    "plem launch bus:=mock record:=false": ("recorder      off (record:=false)",),
}
#: Commands the docs say are refused, with what the refusal names.
REFUSED: dict[str, str] = {"plem launch robots:=robots.yaml": "enp3s0"}


def kind(command: DocCommand) -> str | None:
    """How a command is run: offline, arm (against the launched arm), launch, refused or ethercat; None: unknown."""
    argv = command.argv
    if command.text in REFUSED:
        return "refused"
    if argv[0] != "plem" or len(argv) < 2:
        return None
    name = argv[1]
    if name == "launch":
        if argv[2:] == ["--help"]:
            return "offline"
        if any(argument.startswith(("bus:=ethercat", "eth_interface:=")) for argument in argv):
            return "ethercat"
        return "launch" if "bus:=mock" in argv else None
    if name == "ethercat":
        return "ethercat"
    if name == "doctor":
        return "offline" if all(argument.startswith("-") for argument in argv[2:]) else None
    if name == "profile":
        return "arm" if argv[2:3] == ["calibrate"] else "offline"
    return "offline" if name in OFFLINE else "arm" if name in ON_ARM else None


def runs_until_stopped(command: DocCommand) -> bool:
    """Whether a command runs until Ctrl-C (a watch, a server, a rate, an endless echo or publisher)."""
    argv = command.argv
    return ((argv[1] == "state" and "--watch" in argv) or (argv[1] == "view" and "--help" not in argv)
            or argv[1:3] == ["ethercat", "simulate"]
            or (argv[1:3] == ["topic", "hz"] and "--duration" not in argv)
            or (argv[1:3] in (["topic", "echo"], ["topic", "pub"]) and "--once" not in argv))


def runnable(docs: tuple[Path, ...], wanted: str) -> list[DocCommand]:
    return [command for command in doc_commands(docs) if command.text not in NOT_RUN and kind(command) == wanted]


def docs_with(wanted: str) -> list[Path]:
    return [path for path in DOCS if runnable((path,), wanted)]


# -- every command is run or listed --------------------------------------------------------------------------------
def test_every_doc_command_is_run_or_listed_with_a_reason() -> None:
    problems = []
    for command in doc_commands():
        if command.text in NOT_RUN:
            continue
        if synopsis(command):
            problems.append(f"{command.where()}: a synopsis cannot run; list it in NOT_RUN (tests/docs_commands.py)")
        elif kind(command) is None:
            problems.append(f"{command.where()}: no test runs it; run it in tests/e2e/test_docs_commands.py or "
                            "list it in NOT_RUN with the reason")
        elif runs_until_stopped(command) and command.text not in FIRST_LINES:
            problems.append(f"{command.where()}: runs until Ctrl-C; say in FIRST_LINES what it prints first")
        elif command.text.startswith("plem launch ") and kind(command) == "launch" \
                and command.text not in LAUNCH_SAYS:
            problems.append(f"{command.where()}: a launch; say in LAUNCH_SAYS what its summary shows")
    assert not problems, "\n".join(problems)


def test_the_tables_name_only_commands_the_docs_have() -> None:
    texts = {command.text for command in doc_commands()}
    tables = {"NOT_RUN": NOT_RUN, "FIRST_LINES": FIRST_LINES, "SAYS": SAYS, "LAUNCH_SAYS": LAUNCH_SAYS,
              "REFUSED": REFUSED}
    stale = [f"{table}: {text}" for table, entries in tables.items() for text in entries if text not in texts]
    assert not stale, "no doc has these commands any more:\n" + "\n".join(stale)


def test_extraction_joins_continuations_and_drops_comments_prefixes_and_shown_output() -> None:
    markdown = "\n".join([
        "text", "```sh", "# a comment line", "sudo .venv/bin/plem launch bus:=mock   # the arm's launch",
        "plem topic pub --once /t std_msgs/msg/String \\", '  "{data: a #b,', '    c}"',
        "plem view", "plem view: indy live at http://127.0.0.1:8080", "", "make run", "```",
        "```bash", "ros2 topic list", "```", "```sh", "plem node list", "```"])
    found = commands_of(markdown, "x.md")
    assert [(c.line, c.text, c.sudo) for c in found] == [
        (4, "plem launch bus:=mock", True),
        (5, 'plem topic pub --once /t std_msgs/msg/String "{data: a #b, c}"', False), (8, "plem view", False),
        (11, "make run", False), (17, "plem node list", False)]
    assert found[0].comment == "the arm's launch" and found[1].argv[-1] == "{data: a #b, c}"
    assert found[2].output == ("plem view: indy live at http://127.0.0.1:8080",)
    with pytest.raises(ValueError, match="neither a command nor the output"):
        commands_of("```sh\nls -l\n```\n", "x.md")
    with pytest.raises(ValueError, match="does not end"):
        commands_of('```sh\nplem topic echo "/t\n```\n', "x.md")


# -- running commands ----------------------------------------------------------------------------------------------
def substituted(command: DocCommand, robot_id: str, home: Path) -> list[str]:
    """The command's arguments for the launched robot: its id for the docs' ids, its home for ~ and /data."""
    def one(argument: str) -> str:
        argument = DOC_ROBOT_IDS.sub(robot_id, argument)
        argument = argument.replace("/data/bags", f"{home}/data/bags")
        return f"{home}{argument[1:]}" if argument.startswith("~/") else argument
    return [plem_executable() if index == 0 else one(argument) for index, argument in enumerate(command.argv)]


def broken(text: str) -> bool:
    return any(mark in text for mark in BROKEN)


def run_to_end(command: DocCommand, argv: list[str], cwd: Path, env: dict[str, str], filled: dict[str, str]) -> None:
    """Run a command that ends; it must exit 0 without an internal error and print what the doc says it does."""
    result = subprocess.run(argv, cwd=cwd, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                            timeout=COMMAND_TIMEOUT_S)
    told = f"{command.where()}\n$ {' '.join(argv)}\n--- stdout\n{result.stdout}\n--- stderr\n{result.stderr}"
    assert result.returncode == 0 and not broken(result.stdout + result.stderr), told
    if command.text in SAYS:
        assert SAYS[command.text].format(**filled) in result.stdout, told


def run_until_first_line(command: DocCommand, argv: list[str], cwd: Path, env: dict[str, str],
                         robot_id: str) -> subprocess.Popen[str]:
    """Start a command that runs until Ctrl-C and read its first line, which must be what the doc says."""
    process = subprocess.Popen(argv, cwd=cwd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    first = read_line(process, FIRST_LINE_TIMEOUT_S)
    expected = [FIRST_LINES[command.text].format(robot_id=robot_id)]
    expected += [shown_pattern(line, robot_id) for line in command.output[:1]]
    if not all(re.search(pattern, first) for pattern in expected):
        stop(process)
        raise AssertionError(f"{command.where()}\nfirst line {first!r} does not match {expected}\n"
                             f"--- stderr\n{process.stderr.read() if process.stderr else ''}")
    return process


def stop(process: subprocess.Popen[str]) -> tuple[int, str]:
    """Ctrl-C; the exit status and what the process wrote on stderr."""
    process.send_signal(signal.SIGINT)
    try:
        _, errors = process.communicate(timeout=STOP_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        _, errors = process.communicate()
    return process.returncode, errors


def assert_stops_cleanly(command: DocCommand, process: subprocess.Popen[str]) -> None:
    """Ctrl-C ends the command with 0 or 130 (SIGINT's status), and without an error."""
    code, errors = stop(process)
    assert code in (0, 130) and "ERROR" not in errors and not broken(errors), \
        f"{command.where()}: Ctrl-C ended it with {code}\n--- stderr\n{errors}"


def shown_pattern(line: str, robot_id: str) -> str:
    """A regex of an output line the doc shows: the robot's id for the docs' ids, any number for each number."""
    return "^" + re.sub(r"\d+", r"\\d+", re.escape(DOC_ROBOT_IDS.sub(robot_id, line)))


def run(command: DocCommand, cwd: Path, env: dict[str, str], robot_id: str, home: Path) -> None:
    argv = substituted(command, robot_id, home)
    if runs_until_stopped(command):
        assert_stops_cleanly(command, run_until_first_line(command, argv, cwd, env, robot_id))
    else:
        run_to_end(command, argv, cwd, env, {"robot_id": robot_id, "home": str(home)})


def run_all(commands: list[DocCommand], cwd: Path, env: dict[str, str], robot_id: str, home: Path,
            launch: Launch | None = None) -> None:
    """Run commands in order and report every one that failed, not only the first (a launch that died ends it)."""
    failures = []
    for command in commands:
        try:
            run(command, cwd, env, robot_id, home)
        except (AssertionError, subprocess.TimeoutExpired) as failure:
            failures.append(f"{command.where()}\n{failure}")
        if launch is not None and launch.process.poll() is not None:
            failures.append(f"the arm's launch ended after {command.where()}\n{launch.describe()}")
            break
    assert not failures, f"{len(failures)} of {len(commands)} commands failed:\n\n" + "\n\n".join(failures)


def write_doc_files(path: Path, directory: Path) -> None:
    for name, text in doc_files(path).items():
        (directory / name).write_text(text)


# -- commands without an arm ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("doc", docs_with("offline"), ids=doc_name)
def test_commands_that_need_no_arm(doc: Path, tmp_path: Path) -> None:
    home = tmp_path / "home"
    env = clean_environment(home, PLEM_HOME=str(home / ".plem"))
    write_doc_files(doc, tmp_path)
    run_all(runnable((doc,), "offline"), tmp_path, env, "indy", home)


@pytest.mark.parametrize("doc", docs_with("refused"), ids=doc_name)
def test_commands_the_docs_say_are_refused(doc: Path, tmp_path: Path) -> None:
    for command in runnable((doc,), "refused"):
        named = REFUSED[command.text]
        if Path(f"/sys/class/net/{named}").exists():
            pytest.skip(f"this host has {named}, which the doc's refusal is about")
        write_doc_files(doc, tmp_path)
        result = subprocess.run(substituted(command, "indy", tmp_path), cwd=tmp_path, env=clean_environment(tmp_path),
                                stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=COMMAND_TIMEOUT_S)
        assert result.returncode == 1 and named in result.stderr and "HOW:" in result.stderr, result.stderr
        assert not broken(result.stderr) and READY_LINE not in result.stdout, result.stdout


# -- commands against one launched arm -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    """The docs' `plem launch bus:=mock`, with the planner the planning commands need."""
    with launched_robot(tmp_path_factory, "planner:=true", ros=True) as launch:
        yield launch


def test_the_docs_launch_starts_what_they_say(robot: Launch) -> None:
    home = robot.env["HOME"]
    for text in LAUNCH_SAYS[ARM_LAUNCH]:
        assert text.format(robot_id=robot.robot_id, home=home) in robot.output, robot.describe()


@pytest.mark.parametrize("doc", docs_with("arm"), ids=doc_name)
def test_commands_on_a_launched_arm(doc: Path, robot: Launch, tmp_path: Path) -> None:
    assert robot.process.poll() is None, robot.describe()
    env = {**robot.env, "PLEM_ROBOT_ID": robot.robot_id, "PLEM_HOME": str(tmp_path / ".plem")}
    write_doc_files(doc, tmp_path)
    run_all(runnable((doc,), "arm"), tmp_path, env, robot.robot_id, Path(robot.env["HOME"]), robot)


# -- the docs' other launches --------------------------------------------------------------------------------------
def package_commands() -> list[DocCommand]:
    """The docs' own command that creates the package my_robot_description."""
    return [command for command in runnable(DOCS, "offline") if command.argv[1] == "create-description"][:1]


@pytest.mark.parametrize("command", [c for c in runnable(DOCS, "launch") if c.text != ARM_LAUNCH],
                         ids=lambda command: command.text.removeprefix("plem launch "))
def test_launches_come_up_and_stop_cleanly(command: DocCommand, tmp_path: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    home, robot_id = tmp_path / "home", new_robot_id()
    monkeypatch.chdir(tmp_path)
    env = ros_environment(home)
    if "my_robot_description" in command.text:
        for making in package_commands():
            run(making, tmp_path, env, robot_id, home)
    launch = start_launch([*substituted(command, robot_id, home)[2:], f"robot_id:={robot_id}"], [robot_id],
                          tmp_path, env)
    try:
        for text in LAUNCH_SAYS[command.text]:
            assert text.format(robot_id=robot_id, home=home) in launch.output, launch.describe()
        assert launch.stop() == 0, launch.describe()
        assert not broken(launch.output + launch.errors), launch.describe()
    finally:
        launch.cleanup()


# -- EtherCAT ------------------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.skipif(os.geteuid() != 0, reason="the virtual EtherCAT network needs root (network namespaces, "
                                              "raw sockets), as the docs' `sudo` says")
def test_ethercat_commands(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """In doc order: launches come up and stop cleanly, `ethercat simulate` runs while the commands after it use its
    interface."""
    home, robot_id = tmp_path / "home", new_robot_id()
    monkeypatch.chdir(tmp_path)
    env = ros_environment(home)
    running: list[tuple[DocCommand, subprocess.Popen[str]]] = []
    seen: set[str] = set()
    try:
        for command in runnable(DOCS, "ethercat"):
            if command.text in seen:
                continue
            seen.add(command.text)
            argv = substituted(command, robot_id, home)
            if command.argv[1] == "launch":
                launch = start_launch([*argv[2:], f"robot_id:={robot_id}"], [robot_id], tmp_path, env)
                try:
                    assert launch.stop() == 0 and not broken(launch.output + launch.errors), launch.describe()
                finally:
                    launch.cleanup()
            elif runs_until_stopped(command):
                running.append((command, run_until_first_line(command, argv, tmp_path, env, robot_id)))
            else:
                run_to_end(command, argv, tmp_path, env, {"robot_id": robot_id, "home": str(home)})
    finally:
        for command, process in reversed(running):
            assert_stops_cleanly(command, process)
