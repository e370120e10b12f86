"""Launching robots: bring-up descriptions (component switches) and, later, supervision."""

from plem.launch.description import COMPONENTS, LaunchDescription, LaunchFileError, bringup, load_launch_file

__all__ = ["COMPONENTS", "LaunchDescription", "LaunchFileError", "bringup", "load_launch_file"]
