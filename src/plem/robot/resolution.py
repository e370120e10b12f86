"""Resolve an arm's effective configuration from the five layers, remembering each field's source.

Precedence, highest first: programmatic, launch arguments, environment variables, robot profile, model
defaults. `joint_offsets` is the one exception the reference makes: when `robot_serial` is set (by any
layer) the profile's offsets are used, because they calibrate that physical unit; otherwise offsets set
in code apply, else zeros.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from plem.core.config.layers import Layer, LayerKind, Source, merge_layers
from plem.core.config.settings import Setting
from plem.errors import ConfigError, PlemError, raise_collected
from plem.robot.config import ARM_SETTINGS, SerialArmConfig
from plem.robot.models import DEFAULT_ROBOT_TYPE, ArmPreset, model_for
from plem.robot.profile import RobotProfile

LAUNCH_DEFAULTS: dict[str, Any] = {"robot_id": "indy"}


@dataclass
class ResolvedConfig:
    """The effective config, where each field came from, and warnings raised on the way."""

    config: SerialArmConfig
    sources: dict[str, Source]
    warnings: list[str] = field(default_factory=list)
    profile_path: Path | None = None


def _programmatic_values(programmatic: Mapping[str, Any] | SerialArmConfig | None) -> dict[str, Any]:
    """Fields set in code: a mapping as given, or the fields of a config that differ from its defaults."""
    if programmatic is None:
        return {}
    if isinstance(programmatic, SerialArmConfig):
        baseline = _fresh(type(programmatic), programmatic.dof).field_values()
        return {name: value for name, value in programmatic.field_values().items()
                if name != "dof" and value != baseline[name]}
    known = {f.name for f in fields(SerialArmConfig)} - {"dof"}
    unknown = sorted(set(programmatic) - known)
    if unknown:
        raise ConfigError(
            f"Unknown configuration field(s): {', '.join(unknown)}",
            what=f"fields of SerialArmConfig: {', '.join(sorted(known))}",
            why=f"got {', '.join(unknown)}",
            how="check the field names (see `plem config show`)",
        )
    return dict(programmatic)


def _fresh(config_class: type[SerialArmConfig], dof: int) -> SerialArmConfig:
    return config_class() if issubclass(config_class, ArmPreset) else config_class(dof=dof)


def resolve_arm_config(
    robot_type: str | None = None,
    *,
    launch_args: Mapping[str, str] | None = None,
    programmatic: Mapping[str, Any] | SerialArmConfig | None = None,
    environ: Mapping[str, str] | None = None,
    launch_defaults: Mapping[str, Any] | None = None,
    dof: int | None = None,
) -> ResolvedConfig:
    """Merge the layers for one arm and validate the result (all problems are raised together).

    `robot_type` (or the `robot_type` launch argument) picks the model preset; `dof` with no model
    gives a custom arm. `launch_defaults` are `plem launch`'s own defaults (e.g. robot_id 'indy'),
    which sit above model defaults but below every explicit setting.
    """
    env = os.environ if environ is None else environ
    launch = dict(launch_args or {})
    code = _programmatic_values(programmatic)
    config_class = _config_class(robot_type, launch, programmatic, dof)
    model_label = f"model default {config_class.model_name()}"
    defaults = _fresh(config_class, dof or getattr(programmatic, "dof", 0) or 6)

    layers = [Layer(LayerKind.MODEL_DEFAULT), Layer(LayerKind.LAUNCH_DEFAULT), Layer(LayerKind.ENVIRONMENT),
              Layer(LayerKind.LAUNCH_ARGUMENT), Layer(LayerKind.PROGRAMMATIC)]
    model_layer, launch_default_layer, env_layer, launch_layer, code_layer = layers
    for name, value in defaults.field_values().items():
        model_layer.set(name, value, model_label)
    for name, value in (launch_defaults or {}).items():
        launch_default_layer.set(name, value, f"launch default {name}:={value}")
    errors: list[PlemError] = []
    for setting in ARM_SETTINGS:
        text = env.get(setting.env or "", "")
        if text.strip():
            _set_from_text(env_layer, setting, text, f"environment variable {setting.env}",
                           f"environment {setting.env}", errors)
        if setting.launch in launch:
            text = launch[setting.launch]
            origin = f"launch argument {setting.launch}"
            _set_from_text(launch_layer, setting, text, origin, f"{origin}:={text}", errors)
    for name, value in code.items():
        code_layer.set(name, value, "programmatic (set in code)")

    merged = merge_layers(layers)
    warnings: list[str] = []
    profile_path = _apply_profile(merged, env, warnings)
    values = {name: value for name, (value, _) in merged.items() if name != "dof"}
    config = config_class(**values) if issubclass(config_class, ArmPreset) else config_class(dof=defaults.dof, **values)
    sources = {name: source for name, (_, source) in merged.items()}
    errors.extend(config.problems({name: str(source) for name, source in sources.items()}))
    raise_collected(errors, "the arm configuration")
    warnings.extend(config.warnings())
    return ResolvedConfig(config=config, sources=sources, warnings=warnings, profile_path=profile_path)


def _set_from_text(layer: Layer, setting: Setting, text: str, origin: str, detail: str,
                   errors: list[PlemError]) -> None:
    """Parse one text value into `layer`, collecting a malformed value instead of stopping at it."""
    try:
        layer.set(setting.name, setting.from_text(text, origin), detail)
    except PlemError as error:
        errors.append(error)


def _config_class(
    robot_type: str | None,
    launch: Mapping[str, str],
    programmatic: Mapping[str, Any] | SerialArmConfig | None,
    dof: int | None,
) -> type[SerialArmConfig]:
    if isinstance(programmatic, SerialArmConfig):
        return type(programmatic)
    chosen = robot_type or launch.get("robot_type")
    if chosen is None and dof is not None:
        return SerialArmConfig
    return model_for(chosen or DEFAULT_ROBOT_TYPE)


def _apply_profile(merged: dict[str, tuple[Any, Source]], env: Mapping[str, str],
                   warnings: list[str]) -> Path | None:
    """When robot_serial is set, the profile's offsets replace any others (see module docstring)."""
    serial, serial_source = merged.get("robot_serial", (None, None))
    if not serial:
        return None
    profile = RobotProfile.load_from_serial(serial, env)
    path = RobotProfile.default_path(serial, env)
    offsets, offsets_source = merged["joint_offsets"]
    if offsets_source.kind > LayerKind.PROFILE and list(offsets) != list(profile.joint_offsets):
        warnings.append(
            f"joint_offsets {offsets_source} are replaced by the profile {path} because robot_serial "
            f"{serial} is set ({serial_source})"
        )
    merged["joint_offsets"] = (list(profile.joint_offsets), Source(LayerKind.PROFILE, f"profile {path}"))
    return path
