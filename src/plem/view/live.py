"""The arm on this host, read from its shared memory: the seqlocked state block (never a lock the loop takes),
the newest loop statistics, the fault history, the recorder's status file and the description the launch
shares."""

from __future__ import annotations

from plem.bridge.client import DriverGone, RobotClient, connect
from plem.control.events import newest_fault
from plem.ipc.robot_description import read_description
from plem.recording.status import read_status
from plem.view.feed import Snapshot, drives_text, fault_text, latency_text, mode_text, recorder_text


class LiveFeed:
    """Snapshots of a robot launched on this host."""

    def __init__(self, robot_id: str) -> None:
        self.client: RobotClient = connect(robot_id)
        self.robot_id = robot_id
        self.joint_names = self.client.joint_names
        description = read_description(robot_id)
        self.urdf = description.urdf
        self.packages = description.packages
        self._readouts: dict[str, str] = {}

    def snapshot(self, readouts: bool) -> Snapshot | None:
        """The newest cycle's positions; the readouts refreshed when asked. DriverGone once the driver is gone."""
        state = self.client.state()
        if state is None:
            return None
        if readouts:
            self._readouts = self._read_readouts(state.mode, state.faulted, state.drives_enabled)
        return Snapshot(state.position, state.command_position, self._readouts)

    def _read_readouts(self, mode: object, faulted: bool, enabled: bool) -> dict[str, str]:
        stats = self.client.stats() or {}
        interval = stats.get("latency_interval") or {}
        fault = newest_fault(self.client.faults())
        queues = {queue.name: queue for queue in read_status(self.robot_id)}
        return {"mode": mode_text(mode, faulted),  # type: ignore[arg-type]
                "drives": drives_text(enabled, stats.get("drives") or [], self.joint_names),
                "fault": fault_text(faulted, stats.get("fault_reason") or "",
                                    None if fault is None else (fault.reason, fault.wall_time)),
                "latency": latency_text(interval.get("p99_us") if interval else None, stats.get("overruns")),
                "recorder": recorder_text(queues.get("recorder:bag"), "not running")}

    def close(self) -> None:
        """Unmap the robot's shared memory."""
        self.client.close()


__all__ = ["DriverGone", "LiveFeed"]
