"""`plem topic|service|action|node` against a robot brought up with `plem launch bus:=mock`, over real Cyclone DDS.

The launch and every command share a fresh ROS_DOMAIN_ID with discovery limited to localhost. Each command runs
as its own process, as a user runs it; the arm's position is read from shared memory to confirm it moved.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator

import pytest
import yaml

from plem.bridge import connect
from tests.conftest import fresh_domain
from tests.e2e.launched import Launch, launched, new_robot_id, ros_environment, wait_until
from tests.e2e.ros_peer import JOINT_NAMES, TRAJECTORY

NODES = ("controller_manager", "free_drive_controller", "joint_state_broadcaster", TRAJECTORY,
         "robot_state_publisher", "wim_rt_driver")
SECTIONS = ("Subscribers", "Publishers", "Service Servers", "Service Clients", "Action Servers", "Action Clients")
GID = re.compile(r"^GID: ([0-9a-f]{2}\.){15}[0-9a-f]{2}$", re.MULTILINE)
ARRIVED = 1e-3
FJT = "control_msgs/action/FollowJointTrajectory"
SET_MODE = "plem_msgs/action/SetMode"


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    directory = tmp_path_factory.mktemp("ros_cli")
    robot_id = new_robot_id()
    with launched(["bus:=mock", f"robot_id:={robot_id}"], [robot_id], directory,
                  ros_environment(directory / "plem_home")) as launch:
        yield launch


@pytest.fixture
def ns(robot: Launch) -> str:
    assert robot.process.poll() is None, robot.describe()
    return f"/{robot.robot_id}"


def start(robot: Launch | None, *args: str) -> subprocess.Popen[str]:
    """`plem ARGS` on the robot's domain (on the test's own without a robot)."""
    environment = dict(os.environ)
    if robot is not None:
        environment.update({name: robot.env[name] for name in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")})
    return subprocess.Popen([sys.executable, "-m", "plem.cli", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=environment)


def finish(process: subprocess.Popen[str], timeout: float = 30) -> subprocess.CompletedProcess[str]:
    stdout, stderr = process.communicate(timeout=timeout)
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


def plem(robot: Launch | None, *args: str) -> subprocess.CompletedProcess[str]:
    return finish(start(robot, *args))


def ok(result: subprocess.CompletedProcess[str]) -> str:
    assert result.returncode == 0, f"{result.args}\n{result.stdout}\n{result.stderr}"
    assert "Traceback" not in result.stderr
    return result.stdout


def what_why_how(result: subprocess.CompletedProcess[str], code: int) -> str:
    """The error text of a command that failed with `code` and a WHAT/WHY/HOW block, never a traceback."""
    assert result.returncode == code, f"{result.args}\n{result.stdout}\n{result.stderr}"
    assert result.stderr.startswith("ERROR: "), result.stderr
    assert all(f"\n{label}: " in result.stderr for label in ("WHAT", "WHY", "HOW")), result.stderr
    assert "Traceback" not in result.stderr
    return result.stderr


def sections(text: str) -> dict[str, list[str]]:
    """`plem node info` output: section title → its `name: type` lines."""
    found: dict[str, list[str]] = {}
    current = ""
    for line in text.splitlines()[1:]:
        if line.startswith("  ") and not line.startswith("    "):
            current = line.strip().rstrip(":")
            found[current] = []
        elif line.strip():
            found[current].append(line.strip())
    return found


def moved_trajectory(robot: Launch, distance: float, seconds: int) -> tuple[str, list[float]]:
    """A one-point, positions-only trajectory moving joint0 by `distance` rad towards 0, as YAML; and its target."""
    with connect(robot.robot_id) as client:
        position = [float(value) for value in client.live_state().position]
    position[0] += -distance if position[0] > 0 else distance
    names = ", ".join(JOINT_NAMES)
    return (f"{{joint_names: [{names}], points: [{{positions: {position}, time_from_start: {{sec: {seconds}}}}}]}}",
            position)


def joint0_at(robot: Launch, target: float) -> bool:
    with connect(robot.robot_id) as client:
        return abs(float(client.live_state().position[0]) - target) < ARRIVED


# -- node -----------------------------------------------------------------------------------------------------
def test_node_list_names_every_bridge_node_sorted(robot, ns):
    running = [start(robot, "node", "list"), start(robot, "node", "list", "--count-nodes"),
               start(robot, "node", "list", "--all")]
    listed, counted, every = (ok(finish(process)) for process in running)
    names = listed.splitlines()
    assert {f"{ns}/{name}" for name in NODES} <= set(names)
    assert names == sorted(names)
    assert counted == f"{len(names)}\n"
    assert every == listed      # the bridge has no hidden nodes


def test_an_empty_domain_lists_nothing_with_a_warning():
    domain = {"ROS_DOMAIN_ID": str(fresh_domain()), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    running = {kind: subprocess.Popen([sys.executable, "-m", "plem.cli", kind, "list", "--timeout", "0.3"],
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                      env={**os.environ, **domain})
               for kind in ("service", "action", "node")}
    for kind, process in running.items():
        result = finish(process)
        assert result.returncode == 0 and result.stdout == "", result
        assert result.stderr.startswith(f"WARNING: no ROS 2 {kind}s ") and "within 0.3 s" in result.stderr, result


def test_node_info_lists_topics_services_and_actions(robot, ns):
    running = [start(robot, "node", "info", f"{ns}/{TRAJECTORY}"),
               start(robot, "node", "info", f"{ns}/{TRAJECTORY}", "--include-hidden"),
               start(robot, "node", "info", f"{ns}/wim_rt_driver")]
    arm, arm_hidden, driver = (ok(finish(process)) for process in running)
    assert arm.splitlines()[0] == f"{ns}/{TRAJECTORY}"
    found = sections(arm)
    assert tuple(found) == SECTIONS
    assert found["Subscribers"] == [f"{ns}/{TRAJECTORY}/joint_trajectory: trajectory_msgs/msg/JointTrajectory"]
    assert f"{ns}/{TRAJECTORY}/controller_state: control_msgs/msg/JointTrajectoryControllerState" \
        in found["Publishers"]
    assert "/rosout: rcl_interfaces/msg/Log" in found["Publishers"]
    assert f"{ns}/{TRAJECTORY}/get_parameters: rcl_interfaces/srv/GetParameters" in found["Service Servers"]
    assert found["Action Servers"] == [f"{ns}/{TRAJECTORY}/follow_joint_trajectory: {FJT}"]
    assert found["Service Clients"] == found["Action Clients"] == []
    assert "  Service Clients:\n\n  Action Servers:" in arm     # an empty section is an empty line, as in ros2
    assert "_action" not in arm

    hidden = sections(arm_hidden)
    assert f"{ns}/{TRAJECTORY}/follow_joint_trajectory/_action/send_goal: {FJT}_SendGoal" \
        in hidden["Service Servers"]
    assert f"{ns}/{TRAJECTORY}/follow_joint_trajectory/_action/status: action_msgs/msg/GoalStatusArray" \
        in hidden["Publishers"]
    assert hidden["Action Servers"] == found["Action Servers"]

    assert sections(driver)["Action Servers"] == [f"{ns}/wim_rt_driver/set_mode: {SET_MODE}"]
    assert f"{ns}/rt_events: plem_msgs/msg/RtEvent" in sections(driver)["Publishers"]


def test_unknown_names_say_how_to_list_what_exists(robot, ns):
    running = {
        "node": start(robot, "node", "info", f"{ns}/joint_trajectory_controler", "--timeout", "1"),
        "topic": start(robot, "topic", "info", f"{ns}/joint_state", "--timeout", "1"),
        "service": start(robot, "service", "call", f"{ns}/controller_manager/list_controler",
                         "controller_manager_msgs/srv/ListControllers", "--timeout", "1"),
        "action": start(robot, "action", "send_goal", f"{ns}/wim_rt_driver/set_mod", SET_MODE, "{mode: hold}",
                        "--timeout", "1"),
    }
    close = {"node": f"{ns}/{TRAJECTORY}", "topic": f"{ns}/joint_states",
             "service": f"{ns}/controller_manager/list_controllers", "action": f"{ns}/wim_rt_driver/set_mode"}
    for kind, process in running.items():
        result = finish(process)
        error = what_why_how(result, 1)
        assert error.startswith(f"ERROR: unknown {kind} "), error
        assert f"`plem {kind} list`" in error and f"did you mean {close[kind]}" in error, error
        assert "_action" not in error, error


# -- service ------------------------------------------------------------------------------------------------
def test_service_list_shows_names_and_types(robot, ns):
    running = [start(robot, "service", "list"), start(robot, "service", "list", "-t"),
               start(robot, "service", "list", "--include-hidden-services")]
    plain, typed, every = (ok(finish(process)).splitlines() for process in running)
    assert f"{ns}/controller_manager/list_controllers [controller_manager_msgs/srv/ListControllers]" in typed
    assert f"{ns}/wim_rt_driver/get_parameters [rcl_interfaces/srv/GetParameters]" in typed
    assert f"{ns}/controller_manager/list_controllers" in plain and plain == sorted(plain)
    assert not [name for name in plain if "_action" in name]
    assert f"{ns}/wim_rt_driver/set_mode/_action/send_goal" in every


def test_service_call_prints_the_request_and_the_response_as_yaml(robot, ns):
    running = [start(robot, "service", "call", f"{ns}/controller_manager/list_controllers",
                     "controller_manager_msgs/srv/ListControllers"),
               start(robot, "service", "call", f"{ns}/controller_manager/get_parameters",
                     "rcl_interfaces/srv/GetParameters", "{names: [update_rate]}")]
    listed, parameters = (ok(finish(process)) for process in running)
    head, response = listed.split("\nresponse:\n")
    assert head == ("waiting for service to become available...\n"
                    "requester: making request: controller_manager_msgs.srv.ListControllers_Request()\n")
    controllers = {controller["name"]: controller for controller in yaml.safe_load(response)["controller"]}
    assert {TRAJECTORY, "joint_state_broadcaster"} <= set(controllers)
    assert controllers[TRAJECTORY]["type"] == "joint_trajectory_controller/JointTrajectoryController"

    head, response = parameters.split("\nresponse:\n")
    assert "requester: making request: rcl_interfaces.srv.GetParameters_Request(names=['update_rate'])" in head
    value = yaml.safe_load(response)["values"][0]
    assert value["type"] == 2 and value["integer_value"] > 0      # PARAMETER_INTEGER, in Hz


def test_service_call_of_another_type_names_the_right_one(robot, ns):
    error = what_why_how(plem(robot, "service", "call", f"{ns}/controller_manager/list_controllers",
                              "rcl_interfaces/srv/GetParameters", "--timeout", "3"), 1)
    assert "controller_manager_msgs/srv/ListControllers" in error and "`plem service list -t`" in error


# -- action -------------------------------------------------------------------------------------------------
def test_action_list_shows_names_and_types(robot, ns):
    typed, plain = (ok(finish(process)).splitlines() for process in (start(robot, "action", "list", "-t"),
                                                                       start(robot, "action", "list")))
    assert f"{ns}/{TRAJECTORY}/follow_joint_trajectory [{FJT}]" in typed
    assert f"{ns}/wim_rt_driver/set_mode [{SET_MODE}]" in typed
    assert [line.split(" [")[0] for line in typed] == plain


def test_set_mode_goal_succeeds(robot, ns):
    output = ok(plem(robot, "action", "send_goal", f"{ns}/wim_rt_driver/set_mode", SET_MODE, "{mode: hold}",
                     "--feedback"))
    assert output.startswith("Waiting for an action server to become available...\n"
                             "Sending goal:\n    mode: hold\n\nGoal accepted with ID: "), output
    assert re.search(r"^Goal accepted with ID: [0-9a-f]{32}$", output, re.MULTILINE), output
    assert output.endswith("Result:\n    success: true\n    mode: hold\n    message: ''\n\n"
                           "Goal finished with status: SUCCEEDED\n"), output


def test_trajectory_goal_prints_feedback_then_its_result(robot, ns):
    trajectory, target = moved_trajectory(robot, 0.05, 1)
    output = ok(plem(robot, "action", "send_goal", f"{ns}/{TRAJECTORY}/follow_joint_trajectory", FJT,
                     f"{{trajectory: {trajectory}}}", "--feedback"))
    assert output.endswith("Goal finished with status: SUCCEEDED\n"), output
    feedback = output.split("\nFeedback:\n")
    assert len(feedback) > 2, output          # 20 Hz over 1 s
    assert yaml.safe_load(feedback[1].split("\n\n")[0])["joint_names"] == list(JOINT_NAMES)
    result = yaml.safe_load(output.split("\nResult:\n")[1].split("\n\n")[0])
    assert result["error_code"] == 0
    assert wait_until(lambda: joint0_at(robot, target[0]), 5)


def test_refused_goal_ends_aborted_with_exit_code_zero(robot, ns):
    output = ok(plem(robot, "action", "send_goal", f"{ns}/{TRAJECTORY}/follow_joint_trajectory", FJT,
                     "{trajectory: {joint_names: [no_such_joint], points: [{positions: [0.0], "
                     "time_from_start: {sec: 1}}]}}"))
    result = yaml.safe_load(output.split("\nResult:\n")[1].split("\n\n")[0])
    assert result["error_code"] == -2 and "no_such_joint" in result["error_string"]     # INVALID_JOINTS
    assert output.endswith("Goal finished with status: ABORTED\n"), output


def test_ctrl_c_cancels_the_running_goal(robot, ns):
    trajectory, target = moved_trajectory(robot, 0.05, 10)
    process = start(robot, "action", "send_goal", f"{ns}/{TRAJECTORY}/follow_joint_trajectory", FJT,
                    f"{{trajectory: {trajectory}}}")
    assert process.stdout is not None
    lines = []
    while not lines or not lines[-1].startswith("Goal accepted with ID: "):
        line = process.stdout.readline()
        assert line, finish(process)
        lines.append(line)
    process.send_signal(signal.SIGINT)
    result = finish(process)
    assert result.returncode == 130, result
    assert result.stdout.endswith("Canceling goal...\nGoal canceled.\n"), result.stdout
    assert "Goal finished" not in result.stdout and not joint0_at(robot, target[0])


# -- topic ----------------------------------------------------------------------------------------------------
def test_topic_info_counts_and_verbose_endpoints(robot, ns):
    running = [start(robot, "topic", "info", f"{ns}/joint_states"),
               start(robot, "topic", "info", f"{ns}/joint_states", "-v"),
               start(robot, "topic", "info", f"{ns}/robot_description", "--verbose")]
    plain, verbose, latched = (ok(finish(process)) for process in running)
    assert plain.splitlines()[:2] == ["Type: sensor_msgs/msg/JointState", "Publisher count: 1"]
    assert re.fullmatch(r"Subscription count: \d+", plain.splitlines()[2]) and len(plain.splitlines()) == 3

    assert verbose.startswith("Type: sensor_msgs/msg/JointState\n\nPublisher count: 1\n\n"
                              "Node name: joint_state_broadcaster\n"
                              f"Node namespace: {ns}\n"
                              "Topic type: sensor_msgs/msg/JointState\n"
                              "Topic type hash: RIHS01_"), verbose
    publisher = verbose.split("\n\n")[2]
    assert "Endpoint type: PUBLISHER" in publisher and GID.search(publisher), publisher
    assert publisher.endswith("QoS profile:\n  Reliability: RELIABLE\n  History (Depth): KEEP_LAST (10)\n"
                              "  Durability: VOLATILE"), publisher
    assert "\n\nSubscription count: " in verbose

    assert "Node name: robot_state_publisher\n" in latched
    assert "  History (Depth): KEEP_LAST (1)\n  Durability: TRANSIENT_LOCAL\n" in latched


def test_topic_pub_at_a_rate_until_ctrl_c(robot, ns):
    topic = f"{ns}/cli_chatter"
    publisher = start(robot, "topic", "pub", topic, "std_msgs/msg/String", "{data: hello}", "--rate", "20",
                      "--qos-reliability", "best_effort", "--qos-durability", "transient_local")
    try:
        echoed = plem(robot, "topic", "echo", topic, "--count", "2")
        info = plem(robot, "topic", "info", topic, "-v")
    finally:
        publisher.send_signal(signal.SIGINT)
    published = finish(publisher)
    assert ok(echoed) == "data: hello\n---\ndata: hello\n---\n"
    described = ok(info)
    assert "Publisher count: 1\n\nNode name: _NODE_NAME_UNKNOWN_\nNode namespace: _NODE_NAMESPACE_UNKNOWN_\n" \
        "Topic type: std_msgs/msg/String\n" in described, described
    assert "  Reliability: BEST_EFFORT\n  History (Depth): KEEP_LAST (10)\n  Durability: TRANSIENT_LOCAL" \
        in described, described
    assert published.returncode == 130, published
    assert published.stdout.startswith("publisher: beginning loop\n"
                                       "publishing #1: std_msgs.msg.String(data='hello')\n\n"
                                       "publishing #2: std_msgs.msg.String(data='hello')\n\n"), published.stdout


def test_topic_pub_times_waits_for_the_subscriber_and_exits(robot, ns):
    topic = f"{ns}/cli_counter"
    echo = start(robot, "topic", "echo", topic, "--count", "2", "--timeout", "10")
    published = ok(plem(robot, "topic", "pub", topic, "std_msgs/msg/Float64", "{data: 1e-3}", "--times", "2",
                        "-r", "10"))
    assert ok(finish(echo)) == "data: 0.001\n---\ndata: 0.001\n---\n"
    lines = [line for line in published.splitlines() if line and not line.startswith("Waiting for")]
    assert lines == ["publisher: beginning loop", "publishing #1: std_msgs.msg.Float64(data=0.001)",
                     "publishing #2: std_msgs.msg.Float64(data=0.001)"]


def test_topic_pub_once_moves_the_arm(robot, ns):
    trajectory, target = moved_trajectory(robot, 0.05, 2)
    output = ok(plem(robot, "topic", "pub", "--once", f"{ns}/{TRAJECTORY}/joint_trajectory",
                     "trajectory_msgs/msg/JointTrajectory", trajectory))
    lines = [line for line in output.splitlines() if line and not line.startswith("Waiting for")]
    assert lines[0] == "publisher: beginning loop"
    assert lines[1].startswith("publishing #1: trajectory_msgs.msg.JointTrajectory(header=std_msgs.msg.Header(")
    assert "time_from_start=builtin_interfaces.msg.Duration(sec=2, nanosec=0)" in lines[1]
    assert len(lines) == 2
    assert wait_until(lambda: joint0_at(robot, target[0]), 10), "the arm did not reach the published position"


def test_topic_pub_once_without_a_subscriber_is_an_error(robot, ns):
    error = what_why_how(plem(robot, "topic", "pub", "--once", f"{ns}/nobody_listens", "std_msgs/msg/String",
                              "{data: x}", "--timeout", "0.5"), 1)
    assert error.startswith(f"ERROR: no subscription of {ns}/nobody_listens matched within 0.5 s")


# -- what the command line gets wrong ---------------------------------------------------------------------------
JT = "trajectory_msgs/msg/JointTrajectory"
BAD_INPUTS = {
    "unknown_field": (("topic", "pub", "/t", "std_msgs/msg/String", "{dta: x}"),
                      ["at field dta", "has no field 'dta' (did you mean 'data'?)", "data (string)"]),
    "string_given_a_number": (("topic", "pub", "/t", "std_msgs/msg/String", "{data: 5}"),
                              ["data is a string, got an integer 5", "quote"]),
    "nested_path": (("topic", "pub", "/t", JT, "{points: [{positions: [0, a]}]}"),
                    ["at field points[0].positions[1]", "float64, got a string \"a\""]),
    "duration_not_a_mapping": (("topic", "pub", "/t", JT, "{points: [{time_from_start: 2}]}"),
                               ["points[0].time_from_start is a builtin_interfaces/msg/Duration message",
                                "{sec: 0, nanosec: 0}"]),
    "out_of_range": (("topic", "pub", "/t", "std_msgs/msg/UInt8", "{data: 300}"),
                     ["data is uint8, got 300, out of range", "from 0 to 255"]),
    "fixed_array_length": (("topic", "pub", "/t", "unique_identifier_msgs/msg/UUID", "{uuid: [1, 2]}"),
                           ["uuid is uint8[16]: exactly 16 items, got 2"]),
    "not_a_mapping": (("topic", "pub", "/t", "std_msgs/msg/String", "[1, 2]"),
                      ["VALUES is a std_msgs/msg/String message, got a list [1, 2]"]),
    "malformed_yaml": (("topic", "pub", "/t", "std_msgs/msg/String", "{data: [}"),
                       ["VALUES is not valid YAML", "line 1, column 9"]),
    "unknown_type": (("topic", "pub", "/t", "std_msgs/msg/Strin", "{}"),
                     ["message type std_msgs/msg/Strin is not known", "did you mean std_msgs/msg/String?"]),
    "unknown_package": (("topic", "pub", "/t", "acme_msgs/msg/Widget", "{}"),
                        ["no package acme_msgs", "sensor_msgs"]),
    "service_type_for_a_topic": (("topic", "pub", "/t", "rcl_interfaces/srv/GetParameters", "{}"),
                                 ["'rcl_interfaces/srv/GetParameters' is not a ROS 2 message type"]),
    "invalid_topic_name": (("topic", "pub", "/t x", "std_msgs/msg/String"), ["topic '/t x' is not a valid ROS 2"]),
    "once_and_times": (("topic", "pub", "/t", "std_msgs/msg/String", "--once", "--times", "2"),
                       ["--once and --times exclude each other"]),
    "zero_rate": (("topic", "pub", "/t", "std_msgs/msg/String", "--rate", "0"), ["--rate is 0.0"]),
    "echo_invalid_name": (("topic", "echo", "bad name"), ["topic 'bad name' is not a valid ROS 2 name"]),
    "request_field": (("service", "call", "/s", "rcl_interfaces/srv/GetParameters", "{nams: [a]}"),
                      ["does not fit rcl_interfaces/srv/GetParameters_Request", "did you mean 'names'?"]),
    "unknown_service_type": (("service", "call", "/s", "controller_manager_msgs/srv/ListControler"),
                             ["did you mean controller_manager_msgs/srv/ListControllers?"]),
    "service_timeout_nan": (("service", "call", "/s", "controller_manager_msgs/srv/ListControllers", "--timeout",
                             "nan"), ["--timeout must be a number of seconds"]),
    "goal_field": (("action", "send_goal", "/a", SET_MODE, "{mdoe: hold}"),
                   ["GOAL does not fit plem_msgs/action/SetMode_Goal", "did you mean 'mode'?"]),
    "message_type_for_an_action": (("action", "send_goal", "/a", "std_msgs/msg/String", "{}"),
                                   ["is not a ROS 2 action type"]),
    "node_invalid_name": (("node", "info", "no/de/"), ["node 'no/de/' is not a valid ROS 2 name"]),
}


@pytest.mark.parametrize("case", BAD_INPUTS)
def test_bad_command_lines_are_usage_errors(case):
    args, expected = BAD_INPUTS[case]
    error = what_why_how(plem(None, *args), 2)
    assert all(text in error for text in expected), error


def test_yaml_fills_nested_messages_lists_and_times():
    from plem.cli.ros_messages import message_from_yaml, message_repr, plain
    from plem.middleware.types import library

    interfaces = library()
    trajectory = message_from_yaml(interfaces, JT, "{header: {stamp: {sec: 3, nanosec: 5}, frame_id: base}, "
                                   "joint_names: [a, b], points: [{positions: [1, 2.5], "
                                   "time_from_start: {sec: 2, nanosec: 500000000}}, {positions: [0, 0]}]}",
                                   "VALUES")
    assert plain(trajectory) == {
        "header": {"stamp": {"sec": 3, "nanosec": 5}, "frame_id": "base"}, "joint_names": ["a", "b"],
        "points": [{"positions": [1.0, 2.5], "velocities": [], "accelerations": [], "effort": [],
                    "time_from_start": {"sec": 2, "nanosec": 500_000_000}},
                   {"positions": [0.0, 0.0], "velocities": [], "accelerations": [], "effort": [],
                    "time_from_start": {"sec": 0, "nanosec": 0}}]}
    assert all(isinstance(value, float) for value in trajectory.points[0].positions)

    identifier = message_from_yaml(interfaces, "unique_identifier_msgs/msg/UUID", f"uuid: {list(range(16))}", "V")
    assert plain(identifier) == {"uuid": list(range(16))}
    empty = message_from_yaml(interfaces, "std_msgs/msg/Empty", "", "VALUES")
    assert plain(empty) == {} and message_repr(empty) == "std_msgs.msg.Empty()"
    request = message_from_yaml(interfaces, "rcl_interfaces/srv/GetParameters_Request", "{names: [a]}", "VALUES")
    assert message_repr(request) == "rcl_interfaces.srv.GetParameters_Request(names=['a'])"
