"""The recorded arm replayed from the flight recorder's bags: a timeline to scrub and play, with marks at each fault
and mode change, a jump to the seconds before each fault, and the joint values and loop latency plotted beside.

The whole recording is read at a coarse resolution when it is shown; a fault's window (the flight recorder's
seconds before it, and a little after) is read at up to 1 kHz when the user jumps to it, or alone when the replay
opens at a fault.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import viser
import viser.uplot

from plem.errors import PlemError
from plem.launch.arguments import DEFAULTS
from plem.recording.archive import iso_time, read_event_log
from plem.recording.plot import mode_name
from plem.recording.summary import BagError, RobotBags, find_bags, pick_robot, robot_segments
from plem.recording.timeline import Marker, Timeline, read_timeline, recorded_faults, segment_warnings
from plem.view.feed import joints_text
from plem.view.model import ViewModel
from plem.view.readouts import Readouts
from plem.view.scene import ArmScene

#: Samples read for the whole recording, and for a fault's window.
OVERVIEW_POINTS, WINDOW_POINTS = 20_000, 40_000
#: Seconds shown after a fault (the stop that follows it).
AFTER_FAULT_S = 2.0
FRAME_S = 1.0 / 30.0
SPEEDS = ("0.1", "0.25", "0.5", "1", "2")


@dataclass
class Replay:
    """One robot's recording, ready to be shown."""

    bags: RobotBags
    timeline: Timeline              # what is shown: the whole recording (coarse), or a fault's window at full rate
    warnings: list[str] = field(default_factory=list)
    fault: Marker | None = None
    _overview: Timeline | None = None

    @classmethod
    def of_bags(cls, directory: Path, robot: str | None = None, fault: int | None = None) -> Replay:
        """The recording of `robot` (default: the one whose last message is latest); at its `fault`-th fault
        (1-based) if given.

        With a fault only its window is read (the faults are found in rt_events alone), never the whole recording.
        """
        bags, warnings = pick_robot(find_bags(directory), robot, directory, "showing")
        segments = robot_segments(bags)
        warnings += segment_warnings(segments)
        if fault is None:
            overview = read_timeline(bags, max_points=OVERVIEW_POINTS)
            replay = cls(bags, overview, warnings, None, overview)
        else:
            faults = recorded_faults(segments)
            if not 1 <= fault <= len(faults):
                raise BagError(f"there is no fault {fault} in the bags of {bags.robot_id}",
                               what=f"--fault between 1 and {len(faults)}" if faults else "a recorded fault",
                               why=f"{len(faults)} faults recorded", how="`plem bag info DIR` lists the faults"
                               if faults else "leave --fault out to replay the whole recording")
            marker = faults[fault - 1]
            replay = cls(bags, read_timeline(bags, *fault_window(bags, marker), max_points=WINDOW_POINTS), warnings,
                         marker)
        if replay.timeline.description is None:
            raise BagError(f"the bags of {bags.robot_id} hold no robot_description", what="a recording with the "
                           "robot's URDF (/{robot_id}/robot_description, recorded at the start of each segment)",
                           why="these bags were recorded without it", how="record again with this version of plem "
                           "(plem launch ... record:=true), or plot them with `plem bag plot`")
        return replay

    def focus(self, fault: Marker | None) -> None:
        """Read the window around `fault` (the flight recorder's seconds before it) at full rate; None: everything
        (read once, at a coarse resolution)."""
        self.fault = fault
        if fault is None:
            if self._overview is None:
                self._overview = read_timeline(self.bags, max_points=OVERVIEW_POINTS)
            self.timeline = self._overview
            return
        self.timeline = read_timeline(self.bags, *fault_window(self.bags, fault), max_points=WINDOW_POINTS)

    def show(self, server: viser.ViserServer) -> ReplayPage:
        """Draw the replay on `server`'s page."""
        return ReplayPage(server, self)


def fault_window(bags: RobotBags, fault: Marker) -> tuple[int, int]:
    """From the flight recorder's seconds before `fault`, as the recorder logged them (the launch's default when the
    event log does not say), to `AFTER_FAULT_S` after it (ns since the epoch)."""
    try:
        entries = list(read_event_log(bags.directory))
    except PlemError:
        entries = []
    logged = [entry.get("window_s") for entry in entries if entry.get("kind") == "fault"
              and entry.get("cycle") == fault.cycle]
    window = logged[-1] if logged else None
    before = float(window) if isinstance(window, int | float) else float(DEFAULTS["flight_recorder_seconds"])
    return fault.time_ns - int(before * 1e9), fault.time_ns + int(AFTER_FAULT_S * 1e9)


class ReplayPage:
    """The replay's page: the arm at the moment the timeline points at, the controls and the plots."""

    def __init__(self, server: viser.ViserServer, replay: Replay) -> None:
        self.server = server
        self.replay = replay
        timeline = replay.timeline
        model = ViewModel(timeline.description or "", timeline.joint_names)
        self.scene = ArmScene(server, model, prefix=f"{timeline.robot_id}/")
        gui = server.gui
        self.readouts = Readouts(gui, f"replay of {timeline.robot_id}", ("time", "mode", "fault", "latency",
                                                                          "joints"))
        with gui.add_folder("faults and modes", order=1.0):
            self.whole = gui.add_button("the whole recording")
            self.whole.on_click(lambda _: self._focus(None))
            for number, fault in enumerate(timeline.faults(), start=1):
                button = gui.add_button(f"fault {number}: {iso_time(fault.time_ns)} — {fault.label}"[:120],
                                        color="red")
                button.on_click(self._focus_on(fault))
        self.controls: list[Any] = []
        self.playing = threading.Event()
        self._lock = threading.Lock()
        self._build()
        threading.Thread(target=self._play, name="plem-view-replay", daemon=True).start()

    def _build(self) -> None:
        """The timeline, play controls and plots of the window being replayed."""
        for control in self.controls:
            control.remove()
        timeline = self.replay.timeline
        seconds = (timeline.time_ns - timeline.time_ns[0]) / 1e9
        self.seconds = seconds
        gui = self.server.gui
        marks = tuple((round(float((marker.time_ns - timeline.time_ns[0]) / 1e9), 3),
                       "fault" if marker.kind == "fault" else marker.label.split(" → ")[-1])
                      for marker in timeline.markers
                      if timeline.time_ns[0] <= marker.time_ns <= timeline.time_ns[-1])
        step = max(float(np.median(np.diff(seconds))) if len(seconds) > 1 else 0.001, 0.001)
        start = 0      # a fault's window opens its seconds before the fault; the whole recording at its start
        with gui.add_folder("timeline", order=0.5) as folder:
            self.slider = gui.add_slider("time (s)", min=0.0, max=max(float(seconds[-1]), step), step=step,
                                         initial_value=float(seconds[start]), marks=marks or None)
            self.play = gui.add_button("play / pause")
            self.speed = gui.add_dropdown("speed", SPEEDS, initial_value="1")
            clock = timeline.time_ns / 1e9          # uPlot's time axis: seconds since the epoch, shown as clock time
            position = gui.add_uplot((clock, *timeline.position.T), self._series(timeline.joint_names),
                                     title="joint positions (rad)", aspect=2.0)
            latency = gui.add_uplot((clock, timeline.latency_us), self._series(["wake-up latency"]),
                                    title="loop wake-up latency (µs)", aspect=3.0)
        self.controls = [folder, position, latency]
        self.slider.on_update(lambda _: self._show_index(self._index(self.slider.value)))
        self.play.on_click(lambda _: self.playing.clear() if self.playing.is_set() else self.playing.set())
        self._show_index(start)

    @staticmethod
    def _series(labels: list[str]) -> tuple[viser.uplot.Series, ...]:
        """The time axis, then one coloured line per label."""
        colours = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")
        return (viser.uplot.Series(label="time"),
                *(viser.uplot.Series(label=label, stroke=colours[index % len(colours)], width=1.5)
                  for index, label in enumerate(labels)))

    def _index(self, seconds: float) -> int:
        """The sample at `seconds` from the window's start (the last one past its end)."""
        return min(int(np.searchsorted(self.seconds, seconds)), len(self.seconds) - 1)

    def _show_index(self, index: int) -> None:
        """Draw the arm and the readouts as they were at sample `index`."""
        timeline = self.replay.timeline
        with self._lock:
            self.scene.show(timeline.position[index], timeline.command_position[index])
        time_ns = int(timeline.time_ns[index])
        faults = [marker for marker in timeline.markers if marker.kind in ("fault", "fault_cleared")
                  and marker.time_ns <= time_ns]
        fault = faults[-1].label if faults and faults[-1].kind == "fault" else "none"
        self.readouts.update({"time": f"{iso_time(time_ns)} (+{self.seconds[index]:.3f} s)",
                              "mode": mode_name(int(timeline.mode[index])), "fault": fault,
                              "latency": f"{timeline.latency_us[index]:.0f} µs",
                              "joints": joints_text(timeline.joint_names, timeline.position[index])})

    def _focus_on(self, fault: Marker) -> Callable[[Any], None]:
        """A click handler that jumps to `fault`."""
        return lambda _: self._focus(fault)

    def _focus(self, fault: Marker | None) -> None:
        self.playing.clear()
        self.replay.focus(fault)
        self._build()

    def _play(self) -> None:
        """Advance the timeline while playing, at the chosen speed."""
        while True:
            self.playing.wait()
            value = float(self.slider.value) + FRAME_S * float(self.speed.value)
            if value >= self.seconds[-1]:
                value = float(self.seconds[-1])
                self.playing.clear()
            self.slider.value = value  # type: ignore[misc]  # viser's setter is declared apart from its getter
            self._show_index(self._index(value))
            time.sleep(FRAME_S)
