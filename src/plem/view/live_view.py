"""The live view: the arm redrawn from its feed at a fixed rate, the readouts beside it, the planner's scene and
plan, and (on this host) the teach panel.

The feed is read, never waited on: shared memory through its seqlock, DDS by taking what arrived. The page's
clients are served by viser's own threads; a browser that stalls only fills its own queue in this process.
"""

from __future__ import annotations

import threading
import time
from collections import deque

import numpy as np
import viser

from plem.bridge.client import DriverGone, RobotClient
from plem.view.feed import READOUTS, Feed, joints_text
from plem.view.model import ViewModel
from plem.view.planning import PlannerWatch
from plem.view.readouts import Readouts
from plem.view.scene import ArmScene
from plem.view.teach import TeachPanel

#: Redraws per second asked for: 40, so that at least 30 reach the page on a busy 2-core machine (BENCHMARKS.md).
DEFAULT_RATE_HZ = 40.0
#: Readouts (statistics, faults, recorder) are refreshed this often; positions every frame.
READOUT_PERIOD_S = 0.25
#: Frames whose times give the update rate shown.
RATE_WINDOW = 60


class LiveView:
    """One arm's live page."""

    def __init__(self, server: viser.ViserServer, feed: Feed, *, planner: bool, teach: RobotClient | None = None,
                 teach_note: str = "") -> None:
        """`teach`: the command connection the teach panel moves the arm through (None: no panel); `teach_note`:
        why there is none, shown in its place."""
        self.server = server
        self.feed = feed
        self.model = ViewModel(feed.urdf, feed.joint_names, feed.packages)
        self.scene = ArmScene(server, self.model, prefix=f"{feed.robot_id}/")
        labels = [*READOUTS, "joints", "planner", "view", *(["meshes"] if self.model.missing else [])]
        self.readouts = Readouts(server.gui, f"robot {feed.robot_id}", labels)
        self.position: np.ndarray | None = None
        self.watch = PlannerWatch(feed.robot_id, self.scene, lambda: self.position) if planner else None
        self.teach = (TeachPanel(server, teach, self.scene, lambda: bool(self.watch and self.watch.running))
                      if teach is not None else None)
        if teach_note:
            with server.gui.add_folder("Teach", expand_by_default=False):
                server.gui.add_markdown(teach_note)
        if self.model.missing:
            self.readouts.update({"meshes": f"{len(self.model.missing)} not found, those links show less (add their "
                                            f"package's folder to PLEM_PACKAGE_PATH): "
                                            f"{', '.join(self.model.missing[:5])}"})
        self.frames: deque[float] = deque(maxlen=RATE_WINDOW)

    def rate_hz(self) -> float:
        """Frames read and drawn per second, over the last RATE_WINDOW frames."""
        if len(self.frames) < 2:
            return 0.0
        return (len(self.frames) - 1) / (self.frames[-1] - self.frames[0])

    def run(self, stop: threading.Event, rate_hz: float = DEFAULT_RATE_HZ) -> None:
        """Redraw at `rate_hz` until `stop`; a gone driver is shown, and the page stays with the last pose."""
        if self.watch is not None:
            threading.Thread(target=self.watch.run, args=(stop,), name="plem-view-planner", daemon=True).start()
        period = 1.0 / rate_hz
        next_frame = next_readouts = time.monotonic()
        while not stop.is_set():
            now = time.monotonic()
            due = now >= next_readouts
            try:
                snapshot = self.feed.snapshot(due)
            except DriverGone as error:
                self.readouts.update({"mode": f"driver gone: {error.why}"})
                stop.wait(READOUT_PERIOD_S)
                continue
            if snapshot is not None:
                self.position = snapshot.position
                self.scene.show(snapshot.position, snapshot.command_position)
                self.frames.append(now)
                if due:
                    self.readouts.update({**snapshot.readouts, **self._own(snapshot.position)})
            if due:
                next_readouts = now + READOUT_PERIOD_S
            next_frame = max(next_frame + period, time.monotonic())
            stop.wait(max(0.0, next_frame - time.monotonic()))

    def _own(self, position: np.ndarray) -> dict[str, str]:
        values = {"joints": joints_text(self.feed.joint_names, position),
                  "view": f"{self.rate_hz():.1f} Hz, {len(self.server.get_clients())} browsers connected"}
        if self.watch is not None:
            values["planner"] = self.watch.state
        return values
