"""Robot modes and the transitions a user may request between them."""

from __future__ import annotations

from enum import IntEnum

from plem.errors import CommandRejected


class Mode(IntEnum):
    """What the loop is doing with the drives; the value is what the state block carries."""

    IDLE = 0          # drives disabled, joints held by their brakes
    HOLD = 1          # drives enabled, holding the commanded position
    TRAJECTORY = 2    # executing a trajectory or a point-to-point motion
    FREE_DRIVE = 3    # gravity-compensated, the arm can be moved by hand
    FAULT = 4         # stopped smoothly after a fault; needs reset_fault()

    def __str__(self) -> str:
        """The lower-case name, as commands take it: 'hold', 'free_drive'."""
        return self.name.lower()

    @classmethod
    def parse(cls, value: str | int | Mode) -> Mode:
        """A Mode from its name (any case, '-' or '_') or number, else CommandRejected."""
        if isinstance(value, Mode):
            return value
        try:
            if isinstance(value, int):
                return cls(value)
            return cls[str(value).strip().upper().replace("-", "_")]
        except (KeyError, ValueError):
            names = ", ".join(m.name.lower() for m in cls)
            raise CommandRejected(f"unknown mode {value!r}", what=f"one of {names}", why=f"got {value!r}",
                                  how="pass e.g. hold or free_drive") from None


#: Transitions `set_mode` accepts. TRAJECTORY is entered by starting a motion; FAULT only by a fault and
#: left only by reset_fault().
REQUESTABLE: dict[Mode, frozenset[Mode]] = {
    Mode.IDLE: frozenset({Mode.IDLE, Mode.HOLD, Mode.FREE_DRIVE}),
    Mode.HOLD: frozenset({Mode.HOLD, Mode.IDLE, Mode.FREE_DRIVE}),
    Mode.TRAJECTORY: frozenset({Mode.HOLD}),
    Mode.FREE_DRIVE: frozenset({Mode.FREE_DRIVE, Mode.HOLD, Mode.IDLE}),
    Mode.FAULT: frozenset(),
}

_HOW = {
    Mode.FAULT: "call reset_fault() (CLI: `plem reset`) once the cause is gone",
    Mode.TRAJECTORY: "start a motion (move_joints or a trajectory) while holding; "
                     "to stop a motion use stop() or set_mode('hold')",
}


def check_transition(current: Mode, requested: Mode) -> None:
    """Raise CommandRejected when `set_mode(requested)` is not allowed from `current`."""
    if requested in REQUESTABLE[current]:
        return
    if current is Mode.FAULT:
        how = _HOW[Mode.FAULT]
    elif requested in _HOW:
        how = _HOW[requested]
    else:
        how = "stop the motion first (stop() or set_mode('hold')), then change the mode"
    allowed = ", ".join(m.name for m in sorted(REQUESTABLE[current])) or "none (reset the fault)"
    raise CommandRejected(f"cannot change mode from {current.name} to {requested.name}",
                          what=f"a transition allowed from {current.name}: {allowed}",
                          why=f"{requested.name} was requested while the robot is in {current.name}", how=how)
