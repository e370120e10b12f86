"""Configuration: YAML loading, settings from text, layered resolution, environment variables."""

from plem.core.config.launch_args import parse_launch_arguments
from plem.core.config.layers import Layer, LayerKind, Source, merge_layers
from plem.core.config.loader import ConfigLoader, load_config, load_config_optional

__all__ = [
    "ConfigLoader", "Layer", "LayerKind", "Source", "load_config", "load_config_optional", "merge_layers",
    "parse_launch_arguments",
]
