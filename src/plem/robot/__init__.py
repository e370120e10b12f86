"""Robot configuration: SerialArmConfig, the model presets, profiles and layered resolution.

Profiles and resolution are imported on first use (they pull in pydantic), so commands that only need
the models start faster.
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

from plem.robot.config import SerialArmConfig
from plem.robot.models import (
    MODELS,
    ArmModel,
    ArmPreset,
    Indy7,
    Indy7V2,
    Indy12,
    Indy12V2,
    IndyRP2,
    IndyRP2V2,
    model_for,
)

if TYPE_CHECKING:  # the lazily imported names, typed for checkers
    from plem.robot.profile import RobotProfile
    from plem.robot.resolution import ResolvedConfig, resolve_arm_config
    from plem.robot.robot import Robot, RobotBuilder, RobotFactory

_LAZY = {"RobotProfile": "plem.robot.profile", "ResolvedConfig": "plem.robot.resolution",
         "resolve_arm_config": "plem.robot.resolution", "Robot": "plem.robot.robot",
         "RobotBuilder": "plem.robot.robot", "RobotFactory": "plem.robot.robot"}

__all__ = [
    "MODELS", "ArmModel", "ArmPreset", "Indy7", "Indy7V2", "Indy12", "Indy12V2", "IndyRP2", "IndyRP2V2",
    "ResolvedConfig", "Robot", "RobotBuilder", "RobotFactory", "RobotProfile", "SerialArmConfig", "model_for",
    "resolve_arm_config",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'plem.robot' has no attribute {name!r}")
