"""`plem view`: the arm in 3D in a local web page — live from shared memory or DDS, or replayed from the bags."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from plem.cli.output import print_warnings
from plem.errors import UsageError

if TYPE_CHECKING:
    from plem.view.feed import Feed

RobotArgument = Annotated[str | None, typer.Argument(
    metavar="[ROBOT_ID]", help="Robot to show (default: $PLEM_ROBOT_ID, else indy).", show_default=False)]


def view(
    robot_id: RobotArgument = None,
    ros: Annotated[bool, typer.Option("--ros", help="Read the robot over DDS (robot_description, "
                                                    "joint_states, rt_raw), for a robot on another host.")] = False,
    bag: Annotated[Path | None, typer.Option("--bag", metavar="DIR", help="Replay the recorded arm from the bags "
                                             "under DIR (the recorder's bag_dir, a robot's or a segment).",
                                             show_default=False)] = None,
    robot: Annotated[str | None, typer.Option("--robot", help="With --bag: the robot to replay when DIR holds "
                                              "several (default: the one whose last message is latest).",
                                              show_default=False)] = None,
    fault: Annotated[int | None, typer.Option("--fault", min=1, help="With --bag: open at the N-th recorded fault "
                                              "(1 = the first), the seconds before it.", show_default=False)] = None,
    host: Annotated[str, typer.Option("--host", help="Address to serve on; the teach panel is offered only on "
                                                     "this host's loopback.")] = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", min=0, max=65535, help="Port (the next free one if taken; 0: any "
                                                                     "free one).")] = 8080,
    rate: Annotated[float, typer.Option("--rate", min=1.0, max=120.0, help="Live redraws per second.")] = 40.0,
) -> None:
    """Serve a web page showing the arm in 3D and print its URL; Ctrl-C stops it (the arm runs on)."""
    from plem.bridge.client import default_robot_id
    from plem.launch.component import stop_on_signals
    from plem.view.server import start_server, url

    if bag is None and (robot is not None or fault is not None):
        raise UsageError("--robot and --fault need --bag", what="--robot and --fault with --bag DIR",
                         why="no --bag was given", how="pass --bag DIR to replay recorded bags, or leave them out")
    if bag is not None and (ros or robot_id is not None):
        raise UsageError("--bag replays recorded bags, not a running robot",
                         what="either --bag DIR [--robot ID] or [ROBOT_ID] [--ros]",
                         why="--bag was given with " + ("--ros" if ros else f"ROBOT_ID {robot_id}"),
                         how="pass --robot ID with --bag to pick the recorded robot")
    stop = stop_on_signals()
    if bag is not None:
        from plem.view.replay import Replay

        replay = Replay.of_bags(bag, robot, fault)
        print_warnings(replay.warnings)
        server = start_server(host, port, f"plem replay: {replay.timeline.robot_id}")
        replay.show(server)
        typer.echo(f"plem view: replay of {replay.timeline.robot_id} from {bag} at {url(server)} — Ctrl-C to stop")
        stop.wait()
        server.stop()
        return
    _live(robot_id or default_robot_id(), ros, host, port, rate, stop)


def _live(robot_id: str, ros: bool, host: str, port: int, rate: float, stop: threading.Event) -> None:
    """Serve the live page. The address is printed as soon as the server listens: the browser loads the page while
    the scene is built (the page fills in as it arrives)."""
    from plem.view.server import loopback, start_server, url

    feed: Feed
    if ros:
        from plem.view.ros_feed import RosFeed

        feed, source, teacher, teach_note = RosFeed(robot_id), "DDS", None, ""   # no Teach folder: docs/view.md
    else:
        from plem.view.live import LiveFeed

        live_feed = LiveFeed(robot_id)
        feed, source = live_feed, "shared memory"
        local = loopback(host)
        teacher = live_feed.client if local else None
        teach_note = "" if local else (f"Teach is offered only with --host 127.0.0.1: anyone reaching {host} could "
                                       "move the arm.")
    try:
        server = start_server(host, port, f"plem view: {robot_id}")
        typer.echo(f"plem view: {robot_id} live from {source} at {url(server)} — Ctrl-C to stop (the arm runs on)")
        from plem.view.live_view import LiveView

        live = LiveView(server, feed, planner=not ros, teach=teacher, teach_note=teach_note)
        print_warnings([f"mesh not found: {uri}" for uri in live.model.missing])
        live.run(stop, rate)
        server.stop()
    finally:
        feed.close()
