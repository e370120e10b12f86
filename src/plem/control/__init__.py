"""Control: the real-time loop, modes, limits, trajectory and free-drive controllers, kinematics.

Names are imported on first use: numpy, pinocchio and ruckig load only when control is needed.
"""

from importlib import import_module
from typing import Any

_LAZY = {
    "ArmDynamics": "plem.control.kinematics",
    "ArmLimits": "plem.control.limits",
    "ArmRuntime": "plem.control.runtime",
    "RuntimeSettings": "plem.control.runtime",
    "CommandHandle": "plem.control.commands",
    "CycleLoop": "plem.control.loop",
    "LoopSettings": "plem.control.loop",
    "Event": "plem.control.events",
    "EventKind": "plem.control.events",
    "EventLog": "plem.control.events",
    "FreeDriveController": "plem.control.free_drive",
    "JointState": "plem.control.state",
    "StateBlock": "plem.control.state",
    "Mode": "plem.control.modes",
    "TimingStats": "plem.control.timing",
    "JointTrajectory": "plem.control.trajectory",
    "Spline": "plem.control.spline",
    "TrajectoryPoint": "plem.control.trajectory",
    "TrajectoryTolerances": "plem.control.trajectory",
    "TrajectoryOutcome": "plem.control.trajectory",
    "TrajectoryResult": "plem.control.trajectory",
    "plan_point_to_point": "plem.control.motion",
    "plan_stop": "plem.control.motion",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'plem.control' has no attribute {name!r}")
