"""The teach panel: joint sliders and a tool target to drag, executed only on a click, through the robot's checked
command path (the command socket, as `plem move` uses) at the speed scale shown.

It is off until the user ticks it; ticking it sets the sliders and the target to where the arm is. A motion
that is refused, or fails, shows its WHAT/WHY/HOW on the page; the arm then stays where it is.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from plem.bridge.client import RobotClient
from plem.errors import PlemError
from plem.planning.goals import PlanOptions
from plem.planning.poses import Pose
from plem.view.readouts import plain
from plem.view.scene import ArmScene, matrix_pose

DEFAULT_SPEED_SCALE = 0.25
TARGET_SCALE = 0.15


def _error_text(error: PlemError) -> str:
    return f"**refused:** {plain(error.summary)}  \nWHY: {plain(error.why)}  \nHOW: {plain(error.how)}"


class TeachPanel:
    """Sliders, a draggable target and the buttons that move the arm to them."""

    def __init__(self, server: viser.ViserServer, client: RobotClient, scene: ArmScene,
                 has_planner: Callable[[], bool], order: float = 10.0) -> None:
        self.server = server
        self.client = client
        self.scene = scene
        self.has_planner = has_planner
        gui = server.gui
        limits = client.limits
        with gui.add_folder("Teach", order=order, expand_by_default=False):
            self.enabled = gui.add_checkbox("teach", initial_value=False,
                                            hint="Show the sliders and the target; nothing moves until you click")
            self.speed = gui.add_slider("speed scale", min=0.05, max=1.0, step=0.05, initial_value=DEFAULT_SPEED_SCALE,
                                        disabled=True)
            self.sliders = [gui.add_slider(name, min=float(low) if math.isfinite(low) else -math.pi,
                                           max=float(high) if math.isfinite(high) else math.pi, step=0.001,
                                           initial_value=0.0, disabled=True)
                            for name, low, high in zip(client.joint_names, limits.min_position, limits.max_position,
                                                       strict=True)]
            self.move_joints = gui.add_button("move to the sliders", disabled=True)
            self.move_target = gui.add_button("move the tool to the target", disabled=True)
            self.status = gui.add_markdown("")
        self.target: Any = None
        self._busy = threading.Lock()
        self.enabled.on_update(lambda _: self._toggle())
        self.move_joints.on_click(lambda _: self._start(self._joints))
        self.move_target.on_click(lambda _: self._start(self._to_target))

    def _toggle(self) -> None:
        on = bool(self.enabled.value)
        try:
            state = self.client.state()
        except PlemError as error:
            self.status.content = _error_text(error)
            return
        if on and state is not None:
            for slider, value, low, high in zip(self.sliders, state.position, self.client.limits.min_position,
                                                self.client.limits.max_position, strict=True):
                if not math.isfinite(low) and not math.isfinite(high):   # a continuous joint: a turn either way
                    slider.min, slider.max = float(value) - 2 * math.pi, float(value) + 2 * math.pi
                slider.value = float(value)  # type: ignore[misc]  # viser's setter is declared apart from its getter
            wxyz, position = matrix_pose(self.scene.link_transform(state.position, self.scene.model.tool_link))
            self.target = self.server.scene.add_transform_controls("/teach/target", scale=TARGET_SCALE, wxyz=wxyz,
                                                                   position=position)
        elif self.target is not None:
            self.target.remove()
            self.target = None
        for control in (self.speed, *self.sliders, self.move_joints):
            control.disabled = not on
        self.move_target.disabled = not (on and self.has_planner())
        self.status.content = ("" if not on else f"speed scale {self.speed.value:.2f}: nothing moves until you click"
                               + ("" if self.has_planner() else "; the target needs the planner (an SRDF)"))

    def _start(self, motion: Callable[[], Any]) -> None:
        """Run one motion in a thread of its own (the page stays live); a second click while it runs is ignored."""
        if not self.enabled.value or not self._busy.acquire(blocking=False):
            return
        threading.Thread(target=self._run, args=(motion,), name="plem-view-teach", daemon=True).start()

    def _run(self, motion: Callable[[], Any]) -> None:
        try:
            self.status.content = f"moving at speed scale {self.speed.value:.2f}…"
            handle = motion()
            handle.wait()
            self.status.content = "done"
        except PlemError as error:
            self.status.content = _error_text(error)
        finally:
            self._busy.release()

    def _joints(self) -> Any:
        """To the sliders: planned around the scene when the planner runs, else straight in joint space."""
        target = [float(slider.value) for slider in self.sliders]
        if self.has_planner():
            return self.client.move_to(target, options=self._options())
        return self.client.move_joints(target, speed_scale=self.speed.value)

    def _options(self) -> PlanOptions:
        scale = float(self.speed.value)
        return PlanOptions(velocity_scale=scale, acceleration_scale=scale)

    def _to_target(self) -> Any:
        target = self.target
        if target is None:
            raise PlemError("no target to move to", what="the teach target", why="teach is off",
                            how="tick teach and drag the target")
        w, x, y, z = (float(v) for v in np.asarray(target.wxyz))
        pose = Pose(tuple(float(v) for v in target.position), (x, y, z, w))  # type: ignore[arg-type]
        return self.client.move_to(pose, options=self._options())
