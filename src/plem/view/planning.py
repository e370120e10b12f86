"""The planner as the view sees it: its planning scene's objects and the newest plan, asked for twice a second on
the planner's socket in a thread of its own, so a busy or absent planner never holds up the arm's drawing."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from plem.bridge.planning import PlannerLink
from plem.errors import PlemError
from plem.view.scene import ArmScene

POLL_S = 0.5
#: How long an answer may take: a plan being made holds the planner (requests run one at a time).
ANSWER_S = 60.0


class PlannerWatch:
    """Draws what the robot's planner holds; `state` says whether it runs."""

    def __init__(self, robot_id: str, scene: ArmScene, position: Callable[[], np.ndarray | None]) -> None:
        self.link = PlannerLink(robot_id)
        self.scene = scene
        self.position = position
        self.state = "not asked yet"
        self.running = False
        self._plans_seen = 0
        self._scene_seen = -1
        self._objects: list[dict[str, Any]] = []

    def poll(self) -> None:
        """Ask once; draw a newer plan or scene."""
        try:
            answer = self.link.request("view", ANSWER_S, plans_seen=self._plans_seen, scene_seen=self._scene_seen)
        except PlemError as error:
            self.running, self.state = False, f"not running ({error.summary})"
            self._scene_seen = -1
            return
        self.running = True
        position = self.position()
        plan = answer.get("plan")
        if plan is not None:
            self._plans_seen = int(answer["plans"])
            self.scene.show_path([point["positions"] for point in plan["points"]], float(plan["duration_s"]))
        scene = answer.get("scene")
        if scene is not None:
            self._scene_seen = int(scene["version"])
            self._objects = list(scene["objects"])
        attached = any(entry.get("attached_to") for entry in self._objects)
        if position is not None:
            self.scene.follow_plan(position)
        if position is not None and (scene is not None or attached):
            self.scene.show_objects(self._objects, position)
        self.state = f"running — {len(self._objects)} objects, {self._plans_seen} plans"

    def run(self, stop: threading.Event) -> None:
        """Poll until `stop`."""
        while not stop.is_set():
            self.poll()
            stop.wait(POLL_S)
        self.link.close()
