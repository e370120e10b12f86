"""Model presets: the Indy arms with their model defaults (joint names, encoders, gearing, description).

Encoder resolution and gear ratios are nominal values for this class of arm (16-bit motor encoders,
strain-wave gearing of 121:1 on the large joints and 101:1 on the wrist); override them per model
when the drive documentation says otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

from plem.errors import ConfigError
from plem.robot.config import SerialArmConfig

MOTOR_ENCODER_COUNTS = 2**16
LARGE_JOINT_GEAR = 121.0
WRIST_GEAR = 101.0


@dataclass(frozen=True)
class ArmModel:
    """Constants of one robot model that do not change between units."""

    name: str
    robot_type: str
    joint_names: tuple[str, ...]
    encoder_counts_per_rev: tuple[int, ...]
    gear_ratios: tuple[float, ...]

    @property
    def dof(self) -> int:
        """Number of actuated joints, one per joint name."""
        return len(self.joint_names)

    @property
    def description_package(self) -> str:
        """The built-in description package this model resolves to (`<robot_type>_description`)."""
        return f"{self.robot_type}_description"

    def counts_per_radian(self) -> tuple[float, ...]:
        """Encoder counts per radian at each joint's output, through the gearing."""
        pairs = zip(self.encoder_counts_per_rev, self.gear_ratios, strict=True)
        return tuple(cpr * gear / (2 * math.pi) for cpr, gear in pairs)


def _indy(name: str, robot_type: str, large: int, wrist: int) -> ArmModel:
    dof = large + wrist
    return ArmModel(
        name=name,
        robot_type=robot_type,
        joint_names=tuple(f"joint{i}" for i in range(dof)),
        encoder_counts_per_rev=(MOTOR_ENCODER_COUNTS,) * dof,
        gear_ratios=(LARGE_JOINT_GEAR,) * large + (WRIST_GEAR,) * wrist,
    )


# The presets: SerialArmConfig with the model's DOF fixed, e.g. `Indy7V2(rt_priority=80)`.


@dataclass
class ArmPreset(SerialArmConfig):
    """A SerialArmConfig for a known model: the model fixes `dof`, so it is not a constructor argument."""

    MODEL: ClassVar[ArmModel]
    dof: int = field(init=False)

    def __post_init__(self) -> None:
        self.dof = self.MODEL.dof
        super().__post_init__()


@dataclass
class Indy7(ArmPreset):
    """Indy7, 6 DOF (description package indy7_description)."""

    MODEL: ClassVar[ArmModel] = _indy("Indy7", "indy7", 3, 3)


@dataclass
class Indy7V2(ArmPreset):
    """Indy7 v2, 6 DOF (description package indy7_v2_description)."""

    MODEL: ClassVar[ArmModel] = _indy("Indy7V2", "indy7_v2", 3, 3)


@dataclass
class Indy12(ArmPreset):
    """Indy12, 6 DOF (description package indy12_description)."""

    MODEL: ClassVar[ArmModel] = _indy("Indy12", "indy12", 3, 3)


@dataclass
class Indy12V2(ArmPreset):
    """Indy12 v2, 6 DOF (description package indy12_v2_description)."""

    MODEL: ClassVar[ArmModel] = _indy("Indy12V2", "indy12_v2", 3, 3)


@dataclass
class IndyRP2(ArmPreset):
    """Indy RP2, 7 DOF (description package indyrp2_description)."""

    MODEL: ClassVar[ArmModel] = _indy("IndyRP2", "indyrp2", 4, 3)


@dataclass
class IndyRP2V2(ArmPreset):
    """Indy RP2 v2, 7 DOF (description package indyrp2_v2_description)."""

    MODEL: ClassVar[ArmModel] = _indy("IndyRP2V2", "indyrp2_v2", 4, 3)


MODELS: dict[str, type[ArmPreset]] = {
    preset.MODEL.robot_type: preset
    for preset in (Indy7, Indy7V2, Indy12, Indy12V2, IndyRP2, IndyRP2V2)
}
DEFAULT_ROBOT_TYPE = "indy7_v2"


def model_for(robot_type: str) -> type[ArmPreset]:
    """The preset for a `robot_type` such as 'indy7_v2'."""
    try:
        return MODELS[robot_type]
    except KeyError:
        raise ConfigError(
            f"Unknown robot_type '{robot_type}'",
            what=f"one of the built-in robot types: {', '.join(MODELS)}",
            why=f"robot_type is {robot_type!r}",
            how="pass robot_type:=indy7_v2 (or another listed type), or use description_package:= for other arms",
        ) from None
