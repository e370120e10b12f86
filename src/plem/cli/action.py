"""`plem action list|send_goal`: list ROS 2 actions on the DDS domain and send them goals without a ROS install.

An action is the services and topics under `<action>/_action/` (see plem.middleware.names); a name with a
`send_goal` service is an action, its type the service's without `_SendGoal`. Discovery settings come from
ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE, as for `ros2 action`.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.output import print_warnings
from plem.cli.ros_arguments import LIST_TIMEOUT_S, MAX_SECONDS, interface_type, ros_name, seconds
from plem.cli.ros_messages import message_fields, message_from_yaml, to_yaml
from plem.cli.service import wait_for_server
from plem.cli.topic import WAKE_S
from plem.errors import PlemError

if TYPE_CHECKING:
    from plem.middleware.action import ActionClient

app = typer.Typer(help="List ROS 2 actions on the DDS domain and send them goals (no ROS install needed).",
                  no_args_is_help=True)

#: action_msgs/msg/GoalStatus values by name, as `ros2 action send_goal` prints the final one.
STATUS_NAMES = ("UNKNOWN", "ACCEPTED", "EXECUTING", "CANCELING", "SUCCEEDED", "CANCELED", "ABORTED")
#: action_msgs/srv/CancelGoal return codes by name.
CANCEL_CODES = ("ERROR_NONE", "ERROR_REJECTED", "ERROR_UNKNOWN_GOAL_ID", "ERROR_GOAL_TERMINATED")


@app.command("list")
def list_actions(
    show_types: Annotated[bool, typer.Option("--show-types", "-t", help="Print each action's type.")] = False,
    timeout: Annotated[float, typer.Option("--timeout", callback=seconds, help="Seconds of discovery.")]
    = LIST_TIMEOUT_S,
) -> None:
    """List the ROS 2 actions that servers or clients on the domain announce."""
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node

    node = Node()
    graph = Graph(node)
    graph.discover(timeout)
    actions = graph.actions()
    if not actions:
        print_warnings([f"no ROS 2 actions seen within {timeout} s ({node.settings.describe()})"])
    for name, info in actions.items():
        typer.echo(f"{name} [{', '.join(info.types)}]" if show_types else name)


class _Result:
    """Waits for a goal's result in a thread of its own, so feedback can be printed meanwhile."""

    def __init__(self, client: ActionClient, goal_id: bytes) -> None:
        self.reply: tuple[int, Any] | None = None
        self.failure: BaseException | None = None
        self.done = threading.Event()
        threading.Thread(target=self._wait, args=(client, goal_id), daemon=True).start()

    def _wait(self, client: ActionClient, goal_id: bytes) -> None:
        try:
            self.reply = client.result(goal_id, MAX_SECONDS)   # as ros2, as long as the goal runs
        except BaseException as error:  # noqa: BLE001 - handed to the main thread, which reports it
            self.failure = error
        finally:
            self.done.set()


def _take_feedback(client: ActionClient, goal_id: bytes, show: bool) -> None:
    """Take the feedback messages waiting in the client's reader; with `show`, print those of the goal."""
    for message in client.feedback.take():
        if show and bytes(message.goal_id.uuid) == goal_id:
            typer.echo("Feedback:\n" + to_yaml(message.feedback, indent=4) + "\n")


def _cancel(client: ActionClient, goal_id: bytes, timeout: float) -> None:
    """Ctrl-C while the goal runs: cancel it as ros2 does, then leave as interrupted."""
    from plem.middleware.action import CANCEL_NONE

    typer.echo("Canceling goal...")
    try:
        code = client.cancel(goal_id, timeout)
    except TimeoutError:
        code = None
    if code != CANCEL_NONE:
        answer = "no answer" if code is None else CANCEL_CODES[code] if 0 <= code < len(CANCEL_CODES) else str(code)
        raise PlemError("Failed to cancel goal", what="the action server to cancel the goal",
                        why=f"cancel_goal answered {answer} within {timeout} s; the goal may still run",
                        how="some goals cannot be canceled (e.g. a mode change); watch the outcome on the "
                            "action's status topic or the robot's state")
    typer.echo("Goal canceled.")


@app.command("send_goal")
def send_goal(
    action: Annotated[str, typer.Argument(help="ROS 2 action, e.g. /indy/wim_rt_driver/set_mode.")],
    action_type: Annotated[str, typer.Argument(metavar="TYPE", help="Action type, e.g. plem_msgs/action/SetMode.")],
    goal: Annotated[str, typer.Argument(help="The goal's fields as a YAML mapping, e.g. \"{mode: hold}\"; "
                                        "fields left out are zero.")],
    feedback: Annotated[bool, typer.Option("--feedback", "-f", help="Print the goal's feedback messages.")] = False,
    timeout: Annotated[float, typer.Option("--timeout", callback=seconds, help="Seconds to wait for the action "
                                           "server, and again for it to accept the goal.")] = 5.0,
) -> None:
    """Send one goal and wait for its result (like `ros2 action send_goal`); Ctrl-C cancels the goal.

    The exit code is 0 whatever the goal's final status (SUCCEEDED, ABORTED or CANCELED), which is printed last.
    """
    from plem.middleware.action import ActionClient
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node
    from plem.middleware.types import library

    name = ros_name(action, "action")
    interfaces = library()
    ros_type = interface_type(interfaces, action_type, "action")
    goal_message = message_from_yaml(interfaces, f"{ros_type}_Goal", goal, "GOAL")
    node = Node(interfaces=interfaces)
    client = ActionClient(node, name, ros_type)   # created first: it matches the server while discovery runs
    typer.echo("Waiting for an action server to become available...")
    wait_for_server(Graph(node), node, "action", name, ros_type, timeout,
                    lambda: client.wait_for_server(0) and (not feedback or client.feedback.publishers > 0))
    typer.echo("Sending goal:\n" + to_yaml(goal_message, indent=4) + "\n")
    try:
        goal_id, accepted = client.send_goal(timeout, **message_fields(goal_message))
    except TimeoutError:
        raise PlemError(f"{name} did not answer the goal within {timeout} s", what="the server to accept or "
                        "reject the goal", why="no reply to send_goal arrived in time",
                        how="wait longer with --timeout, or check the action server's log") from None
    if not accepted:
        raise PlemError("Goal was rejected.", what=f"{name} to accept the goal", why="the action server rejected it",
                        how="check the goal's fields and the action server's log")
    try:   # from here on, Ctrl-C cancels the goal
        typer.echo(f"Goal accepted with ID: {goal_id.hex()}\n")
        result = _Result(client, goal_id)
        waitset = node.waitset([client.feedback])
        while not result.done.is_set():
            waitset.wait(int(WAKE_S * 1e9))
            _take_feedback(client, goal_id, feedback)
    except KeyboardInterrupt:
        _cancel(client, goal_id, timeout)
        raise
    if result.reply is None:
        raise PlemError(f"no result from {name}", what="the goal's result",
                        why=f"get_result failed: {result.failure}", how="check the action server's log")
    _take_feedback(client, goal_id, feedback)
    status, outcome = result.reply
    typer.echo("Result:\n" + to_yaml(outcome, indent=4) + "\n")
    typer.echo(f"Goal finished with status: {STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else status}")
