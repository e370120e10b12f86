"""`plem launch`'s supervisor: starts each robot's components as child processes and watches them.

Children start in order with a readiness check (the RT driver announces itself once its loop runs),
in their own session so that Ctrl-C reaches only the supervisor, which then stops them in order: the
driver stops the arm smoothly, disables the drives and removes its shared memory. A child that dies
is reported with its last error line; when an RT driver dies, everything stops. A bridge that dies is started
again (ROS tools would lose the robot without it), at most RESTARTS times in RESTART_WINDOW_S; then the launch
says it gave up and goes on without it. No component but the driver can move or stall the arm: they only read
shared memory and send commands through the driver's command service.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TextIO

from plem.control.loop import OVERRUN_WINDOW_S
from plem.errors import PlemError
from plem.ipc.robot_description import SharedDescription, remove_description, share_description
from plem.launch.child_errors import ErrorTail
from plem.launch.description import COMPONENTS
from plem.launch.plan import RobotPlan, child_environment
from plem.launch.startup import exit_description, first_line
from plem.planning.named_states import ZERO, find_state
from plem.robot.config import RT_KERNEL_FLAG

if TYPE_CHECKING:
    from plem.bridge.client import RobotClient, Stream
    from plem.control.events import Event

STOP_TIMEOUT_S = 20.0
STATUS_PERIOD_S = 0.5
PIPE_STATUS_PERIOD_S = 10.0
#: A component that dies is restarted, unless it already was this many times within RESTART_WINDOW_S.
RESTARTS = 3
RESTART_WINDOW_S = 60.0
#: The components restarted when they die (the others are reported, and the robot runs on without them).
RESTARTED = frozenset({"bridge"})
MODULES = {"ethercat_sim": "plem.launch.ethercat_sim", "rt_driver": "plem.launch.rt_driver",
           "bridge": "plem.launch.ros_bridge", "recorder": "plem.launch.recorder", "planner": "plem.launch.planner"}


class LaunchFailed(PlemError):
    """A component did not start or stopped unexpectedly."""


@dataclass
class Child:
    """One child process of the launch."""

    robot_id: str
    component: str
    process: subprocess.Popen[str]
    critical: bool
    ready: dict[str, Any] = field(default_factory=dict)
    errors: ErrorTail | None = None

    @property
    def label(self) -> str:
        """`[robot_id/component]`, the prefix of the child's lines in the launch's output."""
        return f"[{self.robot_id}/{self.component}]"

    def exit_description(self) -> str:
        """How the child ended: its exit code, or the signal that killed it."""
        return exit_description(self.process.returncode if self.process.returncode is not None else 0)

    def death(self) -> str:
        """How the child ended and, when it said one, its last error line."""
        said = self.errors.last_error() if self.errors is not None else ""
        return f"{self.exit_description()}: {said}" if said else self.exit_description()


class Supervisor:
    """Runs the robots of one launch until a stop signal or a critical child's death."""

    def __init__(self, plans: list[RobotPlan], components: dict[str, bool] | None = None,
                 out: TextIO = sys.stdout) -> None:
        self.plans = plans
        self.components = components or dict.fromkeys(COMPONENTS, True)
        self.out = out
        self.children: list[Child] = []
        self.stop_requested = threading.Event()
        self._clients: dict[str, RobotClient] = {}
        self._restarts: dict[tuple[str, str], list[float]] = {}
        self._event_streams: dict[str, Stream[Event]] = {}

    def say(self, line: str) -> None:
        """Print one line of the launch's output."""
        self._write(line + "\n")

    def _write(self, text: str) -> None:
        """Print; a closed output (the reader of a pipe went away) silences the launch, never stops it."""
        try:
            self.out.write(text)
            self.out.flush()
        except (BrokenPipeError, ValueError):
            self.out = open(os.devnull, "w")  # noqa: SIM115 - lives as long as the launch

    # -- start -------------------------------------------------------------------------------------
    def run(self) -> int:
        """Start everything, watch until stopped, stop everything; the exit code of `plem launch`."""
        previous = {signum: signal.signal(signum, lambda *_: self.stop_requested.set())
                    for signum in (signal.SIGINT, signal.SIGTERM)}
        code = 0
        try:
            for plan in self.plans:
                if self.stop_requested.is_set():
                    break
                self._start_robot(plan)
            if not self.stop_requested.is_set():
                self._summary()
                code = self._watch()
        except PlemError:
            self._stop_all()
            raise
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)
        self._stop_all()
        return code

    def _start_robot(self, plan: RobotPlan) -> None:
        for line in plan.description.log_lines if plan.description else ():
            self.say(f"[{plan.robot_id}] {line}")
        for warning in plan.resolved.warnings:  # as `plem config show` warns
            self.say(f"[{plan.robot_id}] warning: {warning}")
        if plan.planner_wanted and plan.has_srdf and plan.report.planning_disabled is not None:
            self.say(f"[{plan.robot_id}] warning: " + plan.report.planning_disabled.log_text())
        if plan.bus == "ethercat_sim":
            self._start(plan, "ethercat_sim", critical=True)
            if self.stop_requested.is_set():
                return
            plan.arguments["eth_interface"] = self.children[-1].ready["interface"]
        packages = {plan.report.files.name: str(plan.package.resolve())}
        share_description(plan.robot_id, SharedDescription(plan.robot_description, packages, os.getpid()),
                          plan.shm_group)
        self._start(plan, "rt_driver", critical=True)
        if self.stop_requested.is_set():
            return
        # One after the other: starting Python processes together would take the cores from the driver and
        # the drives it is enabling.
        wanted = {"bridge": plan.bridge, "recorder": plan.record, "planner": plan.planner}
        for name, on in wanted.items():
            if on and self.components.get(name, True) and not self.stop_requested.is_set():
                self._start(plan, name, critical=False)

    def _start(self, plan: RobotPlan, component: str, critical: bool) -> None:
        """Start one component as `python -m plem.launch.<module> '<launch arguments>'`; wait for its readiness."""
        env = {**child_environment(plan), "PLEM_LAUNCH_PID": str(os.getpid())}
        arguments = plan.arguments
        if component == "planner" and not self.components.get("bridge", True):
            arguments = {**arguments, "bridge": "false"}  # no DDS when the launch file leaves the bridge out
        # The other components' stderr passes through the launch, which remembers their last error line; a
        # driver's goes straight to the terminal, so that nothing the launch does can stand in its way.
        process = subprocess.Popen([sys.executable, "-m", MODULES[component], json.dumps(arguments)],
                                   stdout=subprocess.PIPE, stderr=None if critical else subprocess.PIPE, text=True,
                                   env=env, start_new_session=True, errors="replace")
        errors = ErrorTail(process.stderr) if process.stderr is not None else None
        child = Child(plan.robot_id, component, process, critical=critical, errors=errors)
        self.children.append(child)
        child.ready = self._await_ready(child)

    def _await_ready(self, child: Child) -> dict[str, Any]:
        """The child's ready announcement; waits while it works (see `startup`), fails with its own error."""
        first = first_line(child.process, child.label, self.say, self.stop_requested.is_set)
        if self.stop_requested.is_set():
            return {}
        announcement: dict[str, Any] = json.loads(first.line) if first.line.startswith("{") else {}
        if announcement.get("ready"):
            return announcement
        error = announcement.get("error", {})
        if error:
            raise LaunchFailed(f"{child.label} could not start: {error.get('summary', 'unknown error')}",
                               what=error.get("what", "a running RT driver"), why=error.get("why", ""),
                               how=error.get("how", "see the messages above"))
        raise LaunchFailed(f"{child.label} did not become ready", what="its ready announcement",
                           why=first.why or f"it printed {first.line.strip()!r}",
                           how="see the messages above; `plem doctor` checks the host")

    def _summary(self) -> None:
        for plan in self.plans:
            children = {child.component: child for child in self.children if child.robot_id == plan.robot_id}
            ready, config = children["rt_driver"].ready, plan.config
            self.say(f"robot {plan.robot_id} ({plan.robot_name}): {config.model_name()}, {ready['dof']} joints, "
                     f"bus {plan.bus}, cycle {ready['cycle_time_us']} µs")
            priority = (f"{ready['policy']} priority {ready['priority']}" if ready["policy"] == "SCHED_FIFO"
                        else f"{ready['policy']} (real-time priority {config.rt_priority} refused)")
            self.say(f"  rt_driver     running, pid {ready['pid']}, {priority}, memory locked: "
                     f"{'yes' if ready['memory_locked'] else 'no'}")
            where = ("its own real-time thread" if ready["loop"] == "core"
                     else "a Python thread, as the bus is written in Python (no real-time guarantee)")
            self.say(f"  core          compiled ({ready['core']}); the cycle runs on {where}")
            origin = ("max_consecutive_overruns:=" + plan.arguments["max_consecutive_overruns"]
                      if plan.arguments.get("max_consecutive_overruns")
                      else f"the default on bus {plan.bus}; max_consecutive_overruns:=N sets it")
            self.say(f"  overruns      counted every {OVERRUN_WINDOW_S:g} s; {plan.max_consecutive_overruns} in a row "
                     f"fault the arm ({origin})")
            for warning in ready["warnings"]:
                self.say(f"  warning: {warning}")
            self.say("  shared memory " + ", ".join(ready["shared_memory"].values()))
            if "ethercat_sim" in children:
                sim = children["ethercat_sim"]
                self.say(f"  ethercat_sim  running, pid {sim.process.pid}, {sim.ready['slaves']} emulated drives "
                         f"behind {sim.ready['interface']} (the virtual EtherCAT network)")
            self.say(f"  bridge        {self._bridge_status(children.get('bridge'))}")
            self.say(f"  recorder      {self._recorder_status(children.get('recorder'))}")
            self.say(f"  planner       {self._planner_status(plan, children.get('planner'))}")
            for warning in children["planner"].ready.get("warnings", []) if "planner" in children else []:
                self.say(f"  warning: {warning}")
        if not RT_KERNEL_FLAG.exists():
            self.say(f"kernel: not PREEMPT_RT ({RT_KERNEL_FLAG} is absent), so nothing bounds how late the loop "
                     "wakes: expect overruns while the machine is busy (docs/runtime.md, Timing)")
        self.say("Ctrl-C stops the arm smoothly and exits. In another terminal: plem state --watch, "
                 f"plem move --to {self._first_state()}, plem topic list")

    def _first_state(self) -> str:
        """The named state to suggest: the first robot's `home` as `plem move` finds it, else `zero`."""
        srdf = self.plans[0].report.srdf if self.plans else None
        return find_state("home", [state.name for state in srdf.group_states] if srdf else []) or ZERO

    def _off(self, component: str, argument: str) -> str:
        """Why a component did not start: the launch file left it out, or its argument is false."""
        return "disabled by the launch file" if not self.components.get(component, True) else f"off ({argument}:=false)"

    def _bridge_status(self, child: Child | None) -> str:
        if child is None:
            return self._off("bridge", "bridge")
        ready = child.ready
        served = ("topics and actions under" if ready["commands"]
                  else "read-only (bridge_commands:=false), topics only under")
        return (f"running, pid {child.process.pid}, {served} {ready['namespace']}/ "
                f"({ready['domain']}, joint_states {ready['joint_state_rate']:g} Hz)")

    def _recorder_status(self, child: Child | None) -> str:
        if child is None:
            return self._off("recorder", "record")
        return f"recording, pid {child.process.pid}, into {child.ready['directory']} ({child.ready['settings']})"

    def _planner_status(self, plan: RobotPlan, child: Child | None) -> str:
        if child is None:
            if not plan.has_srdf:
                return "not started: no SRDF (add srdf/NAME.srdf to plan motions)"
            if plan.report.planning_disabled is not None:
                return f"not started: {plan.report.planning_disabled.summary} (see the warning above)"
            return self._off("planner", "planner")
        ready = child.ready
        objects = f", {ready['objects']} scene objects" if ready["objects"] else ""
        ros = f"MoveIt's services under {ready['namespace']}/" if ready.get("namespace") else "no ROS (bridge:=false)"
        return (f"running, pid {child.process.pid}, groups {', '.join(ready['groups'])}{objects}, {ros} "
                f"(plem move --to-pose, plem plan)")

    # -- watch -------------------------------------------------------------------------------------
    def _watch(self) -> int:
        from plem.bridge.client import connect

        for plan in self.plans:
            client = connect(plan.robot_id)
            self._clients[plan.robot_id] = client
            self._event_streams[plan.robot_id] = client.events(timeout=0)
        interactive = self.out.isatty()
        period = STATUS_PERIOD_S if interactive else PIPE_STATUS_PERIOD_S
        next_status = time.monotonic() + period
        while not self.stop_requested.wait(0.1):
            self._print_events(interactive)
            dead = [child for child in self.children if child.process.poll() is not None]
            if dead:
                for child in dead:
                    self._clear_status(interactive)
                    self.say(f"{child.label} {child.death()}")
                if any(child.critical for child in dead):
                    self.say("an RT driver stopped: stopping everything")
                    return 1
                self.children = [child for child in self.children if child not in dead]
                for child in dead:
                    if child.component in RESTARTED:
                        self._restart(child)
            if time.monotonic() >= next_status:
                self._print_status(interactive)
                next_status = time.monotonic() + period
        self._clear_status(interactive)
        return 0

    def _restart(self, child: Child) -> None:
        """Start a component that died again, unless it died RESTARTS times within RESTART_WINDOW_S already; a
        start that fails counts as one of them."""
        key = (child.robot_id, child.component)
        plan = next(plan for plan in self.plans if plan.robot_id == child.robot_id)
        while not self.stop_requested.is_set():
            now = time.monotonic()
            recent = [at for at in self._restarts.get(key, []) if now - at < RESTART_WINDOW_S]
            if len(recent) >= RESTARTS:
                self.say(f"{child.label} gave up restarting it: it died {len(recent) + 1} times within "
                         f"{RESTART_WINDOW_S:.0f} s, the last time {child.death()}. The robot runs on without it; "
                         f"its log lines above, which start with [{child.component}], say why; fix that and "
                         "restart plem launch")
                return
            self._restarts[key] = [*recent, now]
            self.say(f"{child.label} restarting it ({len(recent) + 1} of {RESTARTS} restarts allowed within "
                     f"{RESTART_WINDOW_S:.0f} s)")
            try:
                self._start(plan, child.component, critical=False)
            except LaunchFailed as error:
                child = self.children.pop()   # the one just started
                if child.process.poll() is None:
                    child.process.kill()
                    child.process.wait()
                self.say(f"{child.label} could not be restarted: {error.summary}: {error.why}")
                continue
            if not self.stop_requested.is_set():
                self.say(f"{child.label} restarted, pid {self.children[-1].process.pid}")
            return

    def _print_events(self, interactive: bool) -> None:
        for robot_id, stream in self._event_streams.items():
            for event in stream:
                self._clear_status(interactive)
                self.say(f"[{robot_id}] {event.describe()}")

    def _clear_status(self, interactive: bool) -> None:
        if interactive:
            self._write("\r\033[K")

    def _print_status(self, interactive: bool) -> None:
        parts = [status_line(robot_id, client) for robot_id, client in self._clients.items()]
        text = "  |  ".join(parts)
        if interactive:
            self._write("\r\033[K" + text)
        else:
            self.say(text)

    # -- stop --------------------------------------------------------------------------------------
    def _stop_all(self) -> None:
        """Stop children in reverse start order: each driver stops its arm, then exits; a virtual EtherCAT
        network only after every driver ended, as its drives answer the driver's stop until the end."""
        if any(child.ready for child in self.children):
            self.say("stopping: the arms stop smoothly and their drives are disabled")
        networks = [child for child in self.children if child.component == "ethercat_sim"]
        self._stop_children([child for child in self.children if child not in networks])
        self._stop_children(networks)
        self.children.clear()
        for plan in self.plans:
            remove_description(plan.robot_id)
        self._print_events(interactive=False)  # the shutdown's events: the mappings outlive the unlinked names
        for client in self._clients.values():
            client.close()
        self._clients.clear()
        self._event_streams.clear()

    def _stop_children(self, children: list[Child]) -> None:
        """SIGTERM to `children` (in reverse start order), then wait for each; kill what does not stop in time."""
        for child in reversed(children):
            if child.process.poll() is None:
                child.process.send_signal(signal.SIGTERM)
        for child in reversed(children):
            try:
                child.process.wait(STOP_TIMEOUT_S)
                if child.ready:
                    self.say(f"{child.label} stopped ({child.exit_description()})")
            except subprocess.TimeoutExpired:
                child.process.kill()
                child.process.wait()
                self.say(f"{child.label} did not stop within {STOP_TIMEOUT_S:.0f} s and was killed")


def status_line(robot_id: str, client: RobotClient) -> str:
    """One compact line: mode, cycle, recent latency, overruns, fault reason when faulted."""
    from plem.bridge.client import DriverGone  # the client module loads once a robot is connected

    try:
        state = client.state()
        stats = client.stats() or {}
    except DriverGone:   # its process ended since the last look; the supervisor reports how on its next one
        return f"{robot_id}: driver gone"
    if state is None:
        return f"{robot_id}: starting"
    interval = stats.get("latency_interval", {})
    text = (f"{robot_id}: {state.mode.name:<10} cycle {state.cycle:>9}  latency p99 "
            f"{interval.get('p99_us', 0):.0f} µs max {interval.get('max_us', 0):.0f} µs  "
            f"overruns {stats.get('overruns', 0)}")
    if state.faulted and stats.get("fault_reason"):
        text += f"  fault: {stats['fault_reason']}"
    return text
