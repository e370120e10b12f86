"""The compiled core's Python face: numpy views of its structures, checked against the C layout at import.

Each structure is declared here field by field (pads included) as a numpy dtype with C alignment; at import
every field's offset and size, and each structure's size, are compared with the `offsetof` table the C side
exports, so a change on one side that the other lacks fails loudly instead of reading the wrong bytes.
The functions themselves live in `core` (plem.control._core); each takes these structures as buffers.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from plem.errors import PlemError

_BUILD_HOW = ("reinstall plem so its core is compiled again: `pip install -e .` in the source tree (`make test` does "
              "it), which needs gcc and the Python headers (Debian/Ubuntu: `sudo apt install build-essential "
              "python3-dev`)")

try:
    from plem.control import _core
except ImportError as error:  # the package was installed without building its core
    raise PlemError("plem's compiled core is missing", what="the extension module plem.control._core, built at install",
                    why=str(error), how=_BUILD_HOW) from None

core: Any = _core
_LAYOUT: dict[str, Any] = core.layout()
#: Joints of the largest arm the core drives (the size of every per-joint array).
MAX_JOINTS: int = _LAYOUT["max_joints"]
#: Polynomial coefficients per segment and joint of every motion the core samples.
ORDER: int = _LAYOUT["order"]
#: Segments of the longest stop the core plans.
STOP_SEGMENTS: int = _LAYOUT["stop_segments"]
J = MAX_JOINTS

_MODEL_FIELDS = [
    ("dof", "<i4"), ("pad", "<i4"), ("gravity", "<f8", 3),
    ("parent", "<i4", J), ("kind", "<i4", J), ("arm_index", "<i4", J), ("pad2", "<i4", J),
    ("axis", "<f8", (J, 3)), ("rotation", "<f8", (J, 9)), ("translation", "<f8", (J, 3)),
    ("mass", "<f8", J), ("com", "<f8", (J, 3)), ("inertia", "<f8", (J, 9)),
]
_POWER_FIELDS = [("dof", "<i4"), ("pad", "<i4"), ("wanted", "<i4", J), ("reset", "u1", J), ("sent", "<u2", J)]


def field_types(dtype: np.dtype[Any]) -> dict[str, tuple[Any, ...]]:
    """(dtype, offset) of each field of a structured dtype."""
    return dict(dtype.fields or {})


def _checked(name: str, fields: list[Any]) -> np.dtype[Any]:
    """The aligned dtype of `fields`, after comparing every field's offset and size with the C side's."""
    dtype = np.dtype(fields, align=True)
    table = dict(_LAYOUT[name])
    size = table.pop("__size__")
    ours = {field: (offset, field_type.itemsize) for field, (field_type, offset, *_) in field_types(dtype).items()
            if not field.startswith("pad")}
    if ours != {field: tuple(entry) for field, entry in table.items()} or dtype.itemsize != size:
        differing = sorted(f for f in ours.keys() | table.keys() if ours.get(f) != tuple(table.get(f, ())))
        raise PlemError(f"the compiled core's {name} does not match its Python view",
                        what=f"the same fields at the same offsets on both sides, {size} bytes in all",
                        why=f"Python's view has {dtype.itemsize} bytes; fields that differ: {', '.join(differing)}",
                        how=_BUILD_HOW)
    return dtype


MODEL = _checked("plem_model", _MODEL_FIELDS)
POWER = _checked("plem_power", _POWER_FIELDS)
SIM = _checked("plem_sim", [
    ("dof", "<i4"), ("dynamics", "<i4"), ("dt", "<f8"), ("omega", "<f8"), ("follow", "<f8"), ("deceleration", "<f8"),
    ("pad0", "<f8"),
    *((name, "<f8", J) for name in ("counts", "raw_zero", "friction", "effort", "lower", "upper", "max_error",
                                    "q", "v", "tau", "external", "stop_q", "stop_v")),
    ("spike", "<i8", J), ("stuck", "u1", J), ("latched", "u1", J), ("stopping", "u1", J), ("pad1", "u1", J),
    ("state", "<i4", J), ("statusword", "<u2", J), ("error_code", "<u2", J), ("controlword", "<u2", J),
    ("pad2", "<u2", J),
    ("lost", "<i4"), ("pad3", "<i4"), ("lost_reads", "<i8"), ("lost_frames", "<i8"),
    ("io_target_position", "<i8", J), ("io_velocity_offset", "<i8", J), ("io_torque_offset", "<f8", J),
    ("io_mode", "i1", J), ("pad4", "u1", J),
    ("io_position", "<i8", J), ("io_velocity", "<i8", J), ("io_torque", "<f8", J),
    ("io_statusword", "<u2", J), ("io_error_code", "<u2", J),
    ("power", np.dtype(_POWER_FIELDS, align=True)), ("scratch", "<f8", (8, J)),
    ("model", np.dtype(_MODEL_FIELDS, align=True)),
])


def new(dtype: np.dtype[Any]) -> np.ndarray:
    """One zeroed structure of `dtype`, as the 1-element array the core's functions take."""
    return np.zeros(1, dtype=dtype)


def joints(structure: np.ndarray, field: str, dof: int) -> np.ndarray:
    """A writable view of the first `dof` entries of a per-joint field (e.g. a simulated arm's 'q')."""
    view: np.ndarray = structure[field][0][:dof]
    return view
