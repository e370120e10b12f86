"""Which `<ros2_control>` block of a URDF plem drives, when upstream macros add blocks of their own.

Upstream description macros (Kinova's, the xArm device macro, indy-ros2) always emit a ros2_control block for
their own driver. A package therefore needs exactly one block plem drives, found by its plugin:

1. a block naming plem's plugin (`hardware/HardwareInterface`, or one installed as a `plem.hardware` entry
   point); every other block is ignored, with a warning;
2. without one, a block naming a simulation plugin ros2_control ships (`mock_components/GenericSystem`,
   `fake_components/GenericSystem`): plem runs it on its simulated arm, and ignores the others;
3. otherwise no block qualifies, and validation names the plugins it found.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from plem.description.model import Ros2ControlBlock, UrdfModel

BUILTIN_PLUGIN = "hardware/HardwareInterface"
HARDWARE_ENTRY_POINTS = "plem.hardware"
#: The simulation plugins ros2_control ships; a package whose only candidate block names one runs simulated.
SIMULATION_PLUGINS = ("mock_components/GenericSystem", "fake_components/GenericSystem")


@cache
def registered_plugins() -> frozenset[str]:
    """Names of hardware plugins installed as entry points (scanned only when a package names one)."""
    from importlib.metadata import entry_points

    return frozenset(ep.name for ep in entry_points(group=HARDWARE_ENTRY_POINTS))


def is_plem_plugin(plugin: str | None) -> bool:
    """Whether plem drives a block naming `plugin` as its own: the built-in plugin or a registered entry point."""
    return plugin == BUILTIN_PLUGIN or (plugin is not None and plugin in registered_plugins())


@dataclass(frozen=True)
class HardwareBlocks:
    """The URDF's ros2_control blocks sorted by the rule above: the candidates plem drives (exactly one in a valid
    package), the blocks it ignores, and whether the candidates are simulation plugins."""

    driven: tuple[Ros2ControlBlock, ...]
    ignored: tuple[Ros2ControlBlock, ...]
    simulated: bool


def sort_blocks(blocks: list[Ros2ControlBlock]) -> HardwareBlocks:
    """The blocks plem drives and those it ignores (with no plem or simulation block, all are candidates)."""
    for simulated, chosen in ((False, [b for b in blocks if is_plem_plugin(b.plugin)]),
                              (True, [b for b in blocks if b.plugin in SIMULATION_PLUGINS])):
        if chosen:
            return HardwareBlocks(tuple(chosen), tuple(b for b in blocks if all(b is not c for c in chosen)),
                                  simulated)
    return HardwareBlocks(tuple(blocks), (), False)


def driven_block(urdf: UrdfModel) -> Ros2ControlBlock | None:
    """The ros2_control block plem drives (the first candidate; validation makes sure there is one)."""
    driven = sort_blocks(urdf.ros2_control).driven
    return driven[0] if driven else None
