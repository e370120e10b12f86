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
                                    "q", "v", "tau", "external")),
    ("push", "<f8", 6), ("push_point", "<f8", 3), ("push_body", "<i4"), ("payload_pending", "<i4"),
    ("payload_body", "<f8", 13), ("stop_q", "<f8", J), ("stop_v", "<f8", J),
    ("spike", "<i8", J), ("stuck", "u1", J), ("latched", "u1", J), ("stopping", "u1", J), ("pad1", "u1", J),
    ("state", "<i4", J), ("statusword", "<u2", J), ("error_code", "<u2", J), ("controlword", "<u2", J),
    ("pad2", "<u2", J), ("digital_inputs", "<u4", J),
    ("lost", "<i4"), ("answered", "<i4"), ("lost_reads", "<i8"), ("lost_frames", "<i8"),
    ("io_target_position", "<i8", J), ("io_velocity_offset", "<i8", J), ("io_torque_offset", "<f8", J),
    ("io_mode", "i1", J), ("pad4", "u1", J),
    ("io_position", "<i8", J), ("io_velocity", "<i8", J), ("io_torque", "<f8", J),
    ("io_statusword", "<u2", J), ("io_error_code", "<u2", J),
    ("power", POWER), ("scratch", "<f8", (8, J)), ("model", MODEL),
])


_SETTINGS_FIELDS = [
    ("dof", "<i4"), ("bus", "<i4"), ("dt", "<f8"), ("tracking_tolerance", "<f8"), ("velocity_margin", "<f8"),
    ("position_margin", "<f8"), ("standstill_velocity", "<f8"), ("command_tolerance", "<f8"),
    ("enable_timeout_cycles", "<i8"), ("counts_per_radian", "<f8", J), ("offsets", "<i8", J),
    *((name, "<f8", J) for name in ("min_position", "max_position", "max_velocity", "max_acceleration", "max_jerk",
                                    "max_effort", "damping", "friction", "contact_threshold")),
]
_BASIS_FIELDS = [("sequence", "<u8"), ("generation", "<u8"), ("slot", "<i4"), ("segments", "<i4"),
                 ("start_cycle", "<i8"), ("time", "<f8"), ("rate", "<f8"), ("ramping", "<i4"), ("pad", "<i4"),
                 ("hold_position", "<f8", J)]
_OVERRIDE_FIELDS = [("target", "<f8"), ("factor", "<f8"), ("rate", "<f8"), ("time", "<f8"), ("peaks", "<f8", (3, J))]
_STREAM_FIELDS = [("session", "<u8"), ("timeout_cycles", "<i8"), ("last_cycle", "<i8"), ("last_count", "<u8"),
                  ("last_stamp", "<i8"), ("feed_until", "<i8"), ("kind", "<i4"), ("timed_out", "<i4"),
                  ("internal", "<i4"), ("pad", "<i4"), ("target", "<f8", J), ("feed", "<f8", J)]
_STREAM_BLOCK_FIELDS = [("sequence", "<u8"), ("session", "<u8"), ("count", "<u8"), ("kind", "<i8"),
                        ("stamp_ns", "<i8"), ("checksum", "<u8"), ("pad0", "<u8", 2), ("target", "<f8", J),
                        ("used_session", "<u8"), ("used_count", "<u8"), ("used_cycle", "<i8"), ("latency_ns", "<i8"),
                        ("state", "<i4"), ("pad1", "<i4"), ("speed_override", "<f8"), ("override_target", "<f8"),
                        ("external", "<f8", J), ("wrench", "<f8", 6)]
_RING_FIELDS = [("head", "<u8"), ("pad0", "<u8", 7), ("tail", "<u8"), ("pad1", "<u8", 7), ("dropped", "<u8"),
                ("pad2", "<u8", 7)]
_COMMAND_FIELDS = [("token", "<u8"), ("op", "<i4"), ("mode", "<i4"), ("slot", "<i4"), ("segments", "<i4"),
                   ("basis", "<u8"), ("activation", "<i8"), ("goal", "<u8"), ("has_path", "<i4"), ("has_goal", "<i4"),
                   ("goal_time", "<f8"), ("stopped_velocity", "<f8"), ("path", "<f8", J), ("goal_tolerance", "<f8", J),
                   ("peaks", "<f8", (3, J)), ("value", "<f8"), ("body", "<f8", 13), ("cycles", "<i8")]
_OUTCOME_FIELDS = [("token", "<u8"), ("cycle", "<i8"), ("stage", "<i4"), ("answer", "<i4"), ("mode", "<i4"),
                   ("detail", "<i4"), ("joint", "<i4"), ("pad", "<i4"), ("values", "<f8", 2)]
_EVENT_FIELDS = [("cycle", "<i8"), ("monotonic_ns", "<i8"), ("token", "<u8"), ("kind", "<i4"), ("cause", "<i4"),
                 ("mode", "<i4"), ("previous_mode", "<i4"), ("joint", "<i4"), ("detail", "<i4"), ("values", "<f8", 4)]
#: The core's enumerations and sizes by their C names (PLEM_HOLD, PLEM_ANSWER_STALE, ...).
CONSTANTS: dict[str, int] = dict(_LAYOUT["constants"])
SETTINGS = _checked("plem_settings", _SETTINGS_FIELDS)
BASIS = _checked("plem_basis", _BASIS_FIELDS)
OVERRIDE = _checked("plem_override", _OVERRIDE_FIELDS)
STREAM = _checked("plem_stream", _STREAM_FIELDS)
TERM = _checked("plem_term", [("op", "<i2"), ("measure", "<i2"), ("index", "<i2"), ("pad", "<i2"),
                              ("threshold", "<f8")])
#: One reaction slot of the core (plem.control.reactions writes them).
REACTION = _checked("plem_reaction", [("token", "<u8"), ("motion", "<u8"), ("armed", "<i4"), ("terms", "<i4"),
                                      ("action", "<i4"), ("once", "<i4"),
                                      ("term", TERM, CONSTANTS["PLEM_REACTION_TERMS"]), ("target", "<f8", J)])
#: The armed reactions as the core walks them (its own: Python only reserves the room).
PROGRAM = _checked("plem_program", [
    ("slot", _checked("plem_armed", [("table", "<u8", 4), ("start", "<i2"), ("comparisons", "<i2"), ("pad", "<i4")]),
     CONSTANTS["PLEM_REACTIONS"]),
    ("comparison", _checked("plem_comparison", [("holds_if", "i1"), ("measure", "i1"), ("index", "<i2"), ("pad", "<i4"),
                                                ("threshold", "<f8")]),
     CONSTANTS["PLEM_REACTIONS"] * CONSTANTS["PLEM_CONDITION_COMPARISONS"]),
    ("uses", "<u4"), ("bound", "<u4"), ("was_true", "<u4"), ("pad", "<i4")])
#: The block a client streams samples through (plem.control.streaming).
STREAM_BLOCK = _checked("plem_stream_block", _STREAM_BLOCK_FIELDS)
RING = _checked("plem_ring", _RING_FIELDS)
COMMAND = _checked("plem_command", _COMMAND_FIELDS)
OUTCOME = _checked("plem_outcome", _OUTCOME_FIELDS)
EVENT = _checked("plem_event", _EVENT_FIELDS)
ARM = _checked("plem_arm", [
    ("settings", SETTINGS), ("model", MODEL),
    ("io_position", "<i8", J), ("io_velocity", "<i8", J), ("io_torque", "<f8", J), ("io_statusword", "<u2", J),
    ("io_error_code", "<u2", J), ("io_target_position", "<i8", J), ("io_velocity_offset", "<i8", J),
    ("io_torque_offset", "<f8", J), ("io_mode", "i1", J), ("pad0", "u1", J), ("io_digital_inputs", "<u4", J),
    ("io_inputs_reported", "<u4"), ("pad6", "<i4"), ("io_answered", "<i4"),
    ("power_wanted", "<i4"), ("power_requests", "<u8"), ("power_resets", "<u8"), ("power", POWER),
    ("cycle", "<i8"), ("mode", "<i4"), ("fault_cause", "<i4"), ("communication_ok", "<i4"), ("have_previous", "<i4"),
    ("braking", "<i4"), ("pad1", "<i4"), ("work", "<f8", (6, J)), ("previous_position", "<f8", J),
    ("previous_acceleration", "<f8", J), ("torque", "<f8", J), ("reach", "<f8", (2, J)),
    ("active", "<i4"), ("active_ended", "<i4"), ("active_slot", "<i4"), ("active_segments", "<i4"),
    ("active_token", "<u8"), ("last_start", "<u8"), ("active_start_cycle", "<i8"), ("settle_deadline", "<i8"),
    ("active_cursor", "<i4"),
    ("active_has_path", "<i4"), ("active_has_goal", "<i4"), ("pad2", "<i4"), ("active_goal_time", "<f8"),
    ("active_stopped_velocity", "<f8"), ("active_path", "<f8", J), ("active_goal", "<f8", J),
    ("active_final", "<f8", (3, J)),
    ("pending", "<i4"), ("pending_target", "<i4"), ("pending_deadline", "<i8"), ("pending_token", "<u8"),
    ("pending_enable_sent", "<i4"), ("pad3", "<i4"),
    ("stop_knots", "<f8", STOP_SEGMENTS + 1), ("stop_coefficients", "<f8", STOP_SEGMENTS * ORDER * J),
    ("stop_final", "<f8", 3 * J), ("stop_segments", "<i4"), ("pad4", "<i4"), ("basis", BASIS), ("override", OVERRIDE),
    ("stream", STREAM), ("feeling", "<i4"), ("reacting", "<u4"), ("unsettled", "<i4"), ("commanded", "<i4"),
    ("external", "<f8", J), ("wrench", "<f8", 6),
    ("reactions", REACTION, CONSTANTS["PLEM_REACTIONS"]), ("program", PROGRAM),
    ("commands_index", RING), ("commands", COMMAND, CONSTANTS["PLEM_COMMAND_SLOTS"]),
    ("outcomes_index", RING), ("outcomes", OUTCOME, CONSTANTS["PLEM_OUTCOME_SLOTS"]),
    ("events_index", RING), ("events", EVENT, CONSTANTS["PLEM_EVENT_SLOTS"]),
])

SERIES = _checked("plem_series", [("count", "<i8"), ("total_ns", "<i8"), ("min_ns", "<i8"), ("max_ns", "<i8"),
                                  ("histogram", "<i8", CONSTANTS["PLEM_HISTOGRAM_BINS"]),
                                  ("window", "<i8", CONSTANTS["PLEM_WINDOW"])])
STATS = _checked("plem_stats", [("cycles", "<i8"), ("overruns", "<i8"), ("missed_periods", "<i8"),
                                ("consecutive_overruns", "<i8"), ("policy", "<i4"), ("priority", "<i4"),
                                ("sched_error", "<i4"), ("affinity_error", "<i4"), ("cpus", "<u8"),
                                ("latency", SERIES), ("compute", SERIES)])
MASTER_STATUS = _checked("plem_master_status", [
    ("exchanges", "<i8"), ("lost_frames", "<i8"), ("working_counter_errors", "<i8"), ("bad_cycles", "<i8"),
    ("working_counter", "<i4"), ("expected_working_counter", "<i4"), ("communication_ok", "<i4"), ("pad", "<i4"),
    ("exchange", SERIES)])


#: Bytes of a cache line: structures start on one, so fields that different threads write stay on lines apart.
CACHE_LINE = 64


def new(dtype: np.dtype[Any]) -> np.ndarray:
    """One zeroed structure of `dtype` starting on a cache line, as the 1-element array the core's functions take."""
    raw = np.zeros(dtype.itemsize + CACHE_LINE, np.uint8)
    start = -raw.ctypes.data % CACHE_LINE
    structure: np.ndarray = raw[start:start + dtype.itemsize].view(dtype)
    return structure


def joints(structure: np.ndarray, field: str, dof: int) -> np.ndarray:
    """A writable view of the first `dof` entries of a per-joint field (e.g. a simulated arm's 'q')."""
    view: np.ndarray = structure[field][0][:dof]
    return view


def describe() -> str:
    """The core and its build in one line, for the launch summary and `plem doctor`."""
    build: dict[str, Any] = core.build()
    standard = {201112: "C11", 201710: "C17"}.get(int(build["standard"]), f"C ({build['standard']})")
    sanitized = ", AddressSanitizer" if build["sanitized"] else ""
    return (f"{standard}, {build['compiler']}{sanitized}, up to {build['max_joints']} joints, "
            f"EtherCAT on {build['ethercat']}")
