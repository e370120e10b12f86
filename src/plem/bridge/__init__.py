"""The Python bridge: `connect(robot_id)` to watch and command a robot started by `plem launch`."""

from plem.bridge.client import DriverGone, RemoteHandle, RobotClient, Stream, connect, default_robot_id

__all__ = ["DriverGone", "RemoteHandle", "RobotClient", "Stream", "connect", "default_robot_id"]
