"""`plem topic list|echo|hz` against a publisher in another process, over real Cyclone DDS on a private domain."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from collections.abc import Iterator

import pytest

from tests.conftest import fresh_domain

DESCRIPTION = '<robot name="plem_topic_test"/>'

#: Publishes /t1/joint_states (JointState, 100 Hz), a latched /t1/robot_description (String),
#: /t1/widget of a type plem does not know and the hidden /t1/_action/status, until its stdin closes.
PUBLISHER = textwrap.dedent(f"""
    import sys, threading, time
    from dataclasses import dataclass
    from cyclonedds.idl import IdlStruct
    from plem.middleware.node import Node
    from plem.middleware.qos import DEFAULT, LATCHED

    @dataclass
    class Widget(IdlStruct, typename="acme_msgs::msg::dds_::Widget_"):
        size: int = 0

    node = Node()
    joints = node.publisher("/t1/joint_states", "sensor_msgs/msg/JointState", DEFAULT)
    description = node.publisher("/t1/robot_description", "std_msgs/msg/String", LATCHED)
    widget = node.publisher_of("rt/t1/widget", Widget, DEFAULT, b"")
    hidden = node.publisher("/t1/_action/status", "std_msgs/msg/String", DEFAULT)
    description.publish(description.message(data={DESCRIPTION!r}))
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    print("ready", flush=True)
    start, count = time.monotonic(), 0
    while not stop.wait(max(0.0, start + count * 0.01 - time.monotonic())):
        count += 1
        joints.publish(joints.message(name=["j1", "j2"], position=[0.25, float(count)]))
    node.close()
""")
#: Each test's private domain, never shared with another test of this run.


@pytest.fixture
def environment() -> dict[str, str]:
    """Environment for every process of one test: its own domain, discovered on this host only."""
    return {**os.environ, "ROS_DOMAIN_ID": str(fresh_domain()), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}


@pytest.fixture
def publisher(environment: dict[str, str]) -> Iterator[subprocess.Popen[str]]:
    process = subprocess.Popen([sys.executable, "-c", PUBLISHER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=environment)
    try:
        assert process.stdout is not None and process.stdout.readline() == "ready\n", process.stderr.read()
        yield process
    finally:
        try:
            process.communicate(timeout=5)   # closes stdin: the publisher stops
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
    assert process.returncode == 0


def start_plem_topic(environment: dict[str, str], *args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "plem.cli", "topic", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=environment)


def finish(process: subprocess.Popen[str]) -> subprocess.CompletedProcess[str]:
    stdout, stderr = process.communicate(timeout=20)
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


def plem_topic(environment: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return finish(start_plem_topic(environment, *args))


def test_list_shows_topics_and_types(publisher, environment):
    running = [start_plem_topic(environment, "list", "--timeout", "1", *flags)
               for flags in ((), ("-t",), ("--include-hidden-topics",))]
    plain, typed_run, with_hidden = (finish(process) for process in running)
    assert plain.returncode == 0, plain.stderr
    assert {"/t1/joint_states", "/t1/robot_description", "/t1/widget"} <= set(plain.stdout.split())
    assert "/t1/_action/status" not in plain.stdout and "/t1/_action/status" in with_hidden.stdout.split()
    typed = typed_run.stdout.splitlines()
    assert "/t1/joint_states [sensor_msgs/msg/JointState]" in typed
    assert "/t1/robot_description [std_msgs/msg/String]" in typed
    assert "/t1/widget [acme_msgs/msg/Widget]" in typed


def test_echo_once_prints_the_fields_as_yaml(publisher, environment):
    result = plem_topic(environment, "echo", "/t1/joint_states", "--once")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[-1] == "---" and lines.count("---") == 1
    assert lines[:3] == ["header:", "  stamp:", "    sec: 0"]
    assert lines[lines.index("name:") + 1:lines.index("name:") + 3] == ["- j1", "- j2"]
    assert lines[lines.index("position:") + 1] == "- 0.25"
    assert "velocity: []" in lines


def test_echo_receives_the_latched_description(publisher, environment):
    result = plem_topic(environment, "echo", "t1/robot_description", "--count", "1")
    assert result.returncode == 0, result.stderr
    assert result.stdout == f"data: {DESCRIPTION}\n---\n"


def test_hz_reports_the_publishing_rate(publisher, environment):
    result = plem_topic(environment, "hz", "/t1/joint_states", "--duration", "2")
    assert result.returncode == 0, result.stderr
    rates = [float(line.split(":")[1]) for line in result.stdout.splitlines() if line.startswith("average rate:")]
    assert rates and all(50 < rate < 150 for rate in rates), result.stdout
    assert "std dev:" in result.stdout and "window:" in result.stdout


def test_topic_without_publisher_is_a_what_why_how_error(publisher, environment):
    result = plem_topic(environment, "echo", "/t1/nobody", "--timeout", "1")
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.startswith("ERROR: no publisher of /t1/nobody")
    assert all(f"\n{label}: " in result.stderr for label in ("WHAT", "WHY", "HOW"))
    assert "/t1/joint_states" in result.stderr and "Traceback" not in result.stderr


def test_unknown_type_names_the_type_and_what_is_known(publisher, environment):
    result = plem_topic(environment, "echo", "/t1/widget", "--once")
    assert result.returncode == 1
    assert "acme_msgs/msg/Widget" in result.stderr and "sensor_msgs" in result.stderr
    assert all(f"\n{label}: " in result.stderr for label in ("WHAT", "WHY", "HOW"))


def test_simultaneous_echoes_all_print(publisher, environment):
    """Several `plem topic echo` started at the same moment each join the domain and print a message."""
    echoes = [start_plem_topic(environment, "echo", "/t1/joint_states", "--once", "--timeout", "60")
              for _ in range(3)]
    for echo in echoes:
        stdout, stderr = echo.communicate(timeout=180)
        assert echo.returncode == 0, stderr
        assert "position:" in stdout and stdout.rstrip().endswith("---"), stdout
        assert "Internal error" not in stderr and "Traceback" not in stderr, stderr


def test_discovery_skips_an_endpoint_the_binding_cannot_convert(publisher, environment, monkeypatch):
    """The cyclonedds binding raises a bare Exception for an endpoint it cannot convert (in the batch that
    holds it); discovery loses only that endpoint, as a failing conversion of /t1/widget shows here."""
    import cyclonedds.builtin as builtin

    from plem.middleware.discovery import DiscoverySettings
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node

    def constructor(*fields):
        if fields[3] == "rt/t1/widget":
            raise ValueError("cannot convert")   # what the binding reports as "Callfunc ... errored"
        return builtin.endpoint_constructor(*fields)

    node = Node(DiscoverySettings.from_environment(environment))
    graph = Graph(node)
    for reader in graph._readers.values():
        monkeypatch.setattr(reader, "_constructor", constructor)
    graph.discover(30, until=lambda seen: "/t1/robot_description" in seen.topics()
                   and "/t1/joint_states" in seen.topics())
    topics = graph.topics()
    assert {"/t1/joint_states", "/t1/robot_description"} <= set(topics) and "/t1/widget" not in topics, topics
    node.close()


@pytest.mark.parametrize("args", [("hz", "/t1/joint_states"), ("echo", "/t1/joint_states")], ids=["hz", "echo"])
def test_ctrl_c_while_messages_arrive_exits_130_quietly(publisher, environment, args):
    """Ctrl-C in the middle of a stream of messages ends the command with 130 and nothing on stderr, every time
    (Ctrl-C is noted, not raised inside a DDS call, where it could end the command in a crash)."""
    for _ in range(3):
        process = start_plem_topic(environment, *args)
        assert process.stdout is not None and process.stdout.readline(), process.communicate(timeout=20)
        process.send_signal(signal.SIGINT)
        result = finish(process)
        assert (result.returncode, result.stderr) == (130, ""), result
