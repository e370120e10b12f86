"""Robot configuration: SerialArmConfig, the model presets, profiles and layered resolution."""

from plem.robot.config import SerialArmConfig
from plem.robot.models import MODELS, ArmModel, Indy7, Indy7V2, Indy12, Indy12V2, IndyRP2, IndyRP2V2, model_for
from plem.robot.profile import RobotProfile
from plem.robot.resolution import ResolvedConfig, resolve_arm_config

__all__ = [
    "MODELS", "ArmModel", "Indy7", "Indy7V2", "Indy12", "Indy12V2", "IndyRP2", "IndyRP2V2", "ResolvedConfig",
    "RobotProfile", "SerialArmConfig", "model_for", "resolve_arm_config",
]
