"""Reactions: conditions over what the core measures, each with an action, evaluated by the core every cycle.

A condition is built from measured quantities and thresholds, combined with `&`, `|` and `~`:

    from plem.control.reactions import Measure, Stop
    robot.on(Measure.FORCE_Z > 5.0, Stop())
    robot.move_joints(target, until=Measure.external_torque("joint2") > 8.0)

It travels to the core as a small program in postfix (comparisons, then AND/OR/NOT), written into one of the
core's reaction slots; no Python runs when it is evaluated. The action starts in the cycle the condition becomes
true (the cycle that measured it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from plem.control.compiled import CONSTANTS as C
from plem.errors import CommandRejected

#: Comparisons and combinations a condition may hold (the core's program length).
MAX_TERMS = C["PLEM_REACTION_TERMS"]
_WRENCH = ("force x", "force y", "force z", "torque x", "torque y", "torque z")
_UNITS = {C["PLEM_MEASURE_POSITION"]: "rad", C["PLEM_MEASURE_VELOCITY"]: "rad/s", C["PLEM_MEASURE_EFFORT"]: "N·m",
          C["PLEM_MEASURE_EXTERNAL_TORQUE"]: "N·m", C["PLEM_MEASURE_FOLLOWING_ERROR"]: "rad",
          C["PLEM_MEASURE_MOTION_TIME"]: "s", C["PLEM_MEASURE_DRIVE_STATE"]: "", C["PLEM_MEASURE_DIGITAL_INPUT"]: ""}
#: Bits of a drive's digital inputs (0x60FD is 32 bits wide).
INPUT_BITS = 32


@dataclass(frozen=True)
class Term:
    """One instruction of a condition's program: a comparison (measure, index, threshold) or a combination."""

    op: int
    measure: int = 0
    index: int | str | tuple[int | str, int] = 0   # a digital input: (joint, bit)
    threshold: float = 0.0


@dataclass(frozen=True)
class Condition:
    """A condition in postfix; combine with `&`, `|` and `~`."""

    terms: tuple[Term, ...]
    text: str

    def __and__(self, other: Condition) -> Condition:
        return Condition(self.terms + _condition(other).terms + (Term(C["PLEM_TERM_AND"]),),
                         f"({self.text} and {other.text})")

    def __or__(self, other: Condition) -> Condition:
        return Condition(self.terms + _condition(other).terms + (Term(C["PLEM_TERM_OR"]),),
                         f"({self.text} or {other.text})")

    def __invert__(self) -> Condition:
        return Condition(self.terms + (Term(C["PLEM_TERM_NOT"]),), f"not {self.text}")

    def __bool__(self) -> bool:
        raise CommandRejected("a reaction's condition has no truth value in Python",
                              what="conditions combined with &, | and ~",
                              why="`and`, `or`, `not` and chained comparisons ask Python for a truth value; the "
                                  "condition is evaluated by the robot every cycle",
                              how="write (a > 1) & (b < 2), (a > 1) | (b < 2) or ~(a > 1)")


def _condition(value: object) -> Condition:
    if not isinstance(value, Condition):
        raise CommandRejected("not a reaction condition", what="a condition such as Measure.FORCE_Z > 5.0",
                              why=f"got {type(value).__name__}", how="compare a Measure quantity with a number")
    return value


@dataclass(frozen=True)
class Quantity:
    """Something the core measures every cycle; compare it with a number to get a Condition."""

    measure: int
    index: int | str | tuple[int | str, int]
    name: str

    def _compare(self, op: str, threshold: float) -> Condition:
        if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) or not math.isfinite(threshold):
            raise CommandRejected(f"{self.name} is compared with something that is not a finite number",
                                  what="a finite number as the threshold", why=f"got {threshold!r}",
                                  how=f"write e.g. {self.name} > 5.0")
        code = {">": "PLEM_TERM_ABOVE", "<": "PLEM_TERM_BELOW", "==": "PLEM_TERM_EQUAL"}[op]
        unit = _UNITS.get(self.measure, "N" if isinstance(self.index, int) and self.index < 3 else "N·m")
        return Condition((Term(C[code], self.measure, self.index, float(threshold)),),
                         f"{self.name} {op} {threshold:g}{' ' + unit if unit else ''}")

    def __gt__(self, threshold: float) -> Condition:
        return self._compare(">", threshold)

    def __lt__(self, threshold: float) -> Condition:
        return self._compare("<", threshold)

    def __eq__(self, threshold: object) -> Condition:  # type: ignore[override]
        return self._compare("==", threshold)  # type: ignore[arg-type]

    def __hash__(self) -> int:
        return hash((self.measure, self.index))


class Measure:
    """The quantities a reaction may watch. Joints by name or index; the wrench is at the flange, in the base frame,
    and is what the environment applies (so is the external torque: the model's effort less the measured)."""

    FORCE_X = Quantity(C["PLEM_MEASURE_WRENCH"], 0, "force x")
    FORCE_Y = Quantity(C["PLEM_MEASURE_WRENCH"], 1, "force y")
    FORCE_Z = Quantity(C["PLEM_MEASURE_WRENCH"], 2, "force z")
    TORQUE_X = Quantity(C["PLEM_MEASURE_WRENCH"], 3, "torque x")
    TORQUE_Y = Quantity(C["PLEM_MEASURE_WRENCH"], 4, "torque y")
    TORQUE_Z = Quantity(C["PLEM_MEASURE_WRENCH"], 5, "torque z")
    MOTION_TIME = Quantity(C["PLEM_MEASURE_MOTION_TIME"], 0, "motion time")

    @staticmethod
    def position(joint: int | str) -> Quantity:
        """A joint's measured position (rad)."""
        return Quantity(C["PLEM_MEASURE_POSITION"], joint, f"position of {joint}")

    @staticmethod
    def velocity(joint: int | str) -> Quantity:
        """A joint's measured velocity (rad/s)."""
        return Quantity(C["PLEM_MEASURE_VELOCITY"], joint, f"velocity of {joint}")

    @staticmethod
    def effort(joint: int | str) -> Quantity:
        """A joint's measured effort (N·m)."""
        return Quantity(C["PLEM_MEASURE_EFFORT"], joint, f"effort of {joint}")

    @staticmethod
    def external_torque(joint: int | str) -> Quantity:
        """The estimated external torque on a joint (N·m)."""
        return Quantity(C["PLEM_MEASURE_EXTERNAL_TORQUE"], joint, f"external torque on {joint}")

    @staticmethod
    def following_error(joint: int | str) -> Quantity:
        """How far a joint is from its command (rad, never negative)."""
        return Quantity(C["PLEM_MEASURE_FOLLOWING_ERROR"], joint, f"following error of {joint}")

    @staticmethod
    def drive_state(joint: int | str) -> Quantity:
        """A joint's drive state (compare with a plem.fieldbus.bus.DriveState, e.g. == DriveState.FAULT)."""
        return Quantity(C["PLEM_MEASURE_DRIVE_STATE"], joint, f"drive state of {joint}")

    @staticmethod
    def digital_input(joint: int | str, bit: int) -> Quantity:
        """One bit of a joint's drive's digital inputs (0x60FD), 1 or 0 (compare == 1); never true on a drive that
        does not report them. CiA402: bit 0 negative limit switch, 1 positive, 2 home, 3 interlock, 16-31 the
        manufacturer's inputs."""
        if isinstance(bit, bool) or not isinstance(bit, int) or not 0 <= bit < INPUT_BITS:
            raise CommandRejected("not a digital input's bit", what=f"a bit from 0 to {INPUT_BITS - 1}",
                                  why=f"got {bit!r}", how="e.g. Measure.digital_input('joint5', 16) == 1")
        return Quantity(C["PLEM_MEASURE_DIGITAL_INPUT"], (joint, bit), f"digital input {bit} of {joint}")


@dataclass(frozen=True)
class Stop:
    """End the running motion with the quickest stop within the limits; the arm then holds."""

    code: int = field(default=C["PLEM_REACT_STOP"], init=False)


@dataclass(frozen=True)
class Hold:
    """Pause on the path: the speed override's target becomes 0 (set_speed_override(1) resumes)."""

    code: int = field(default=C["PLEM_REACT_HOLD"], init=False)


@dataclass(frozen=True)
class FreeDrive:
    """End the running motion and switch to free drive (gravity-compensated, damped): a change of control mode."""

    code: int = field(default=C["PLEM_REACT_FREE_DRIVE"], init=False)


@dataclass(frozen=True)
class MoveTo:
    """Follow a joint target (rad) from where the arm is, e.g. a retract, within every limit; then hold."""

    target: Sequence[float]
    code: int = field(default=C["PLEM_REACT_MOVE"], init=False)


@dataclass(frozen=True)
class Record:
    """Record an event only."""

    code: int = field(default=C["PLEM_REACT_RECORD"], init=False)


Action = Stop | Hold | FreeDrive | MoveTo | Record
ACTION_NAMES = {C["PLEM_REACT_STOP"]: "stop", C["PLEM_REACT_HOLD"]: "hold", C["PLEM_REACT_FREE_DRIVE"]: "free drive",
                C["PLEM_REACT_MOVE"]: "move", C["PLEM_REACT_RECORD"]: "record"}


def _joint(index: int | str, joint_names: Sequence[str], what: str) -> int:
    if isinstance(index, str) and index in joint_names:
        return list(joint_names).index(index)
    if isinstance(index, int) and not isinstance(index, bool) and 0 <= index < len(joint_names):
        return index
    raise CommandRejected(f"{what} names no joint of the robot",
                          what=f"a joint name ({', '.join(joint_names)}) or an index from 0 to {len(joint_names) - 1}",
                          why=f"got {index!r}", how="name the joint as the robot's joint_names do")


def write_reaction(slot: np.void, token: int, condition: Condition, action: Action, joint_names: Sequence[str],
                   motion: int = 0, once: bool = False) -> None:
    """Fill a core reaction slot (not armed) with a checked condition and action."""
    condition = _condition(condition)
    if not isinstance(action, (Stop, Hold, FreeDrive, MoveTo, Record)):
        raise CommandRejected("not a reaction action", what="Stop(), Hold(), FreeDrive(), MoveTo(q) or Record()",
                              why=f"got {type(action).__name__}", how="pass one of plem.control.reactions' actions")
    if len(condition.terms) > MAX_TERMS:
        raise CommandRejected("the condition is too long", what=f"at most {MAX_TERMS} comparisons and combinations",
                              why=f"it has {len(condition.terms)}", how="split it into several reactions")
    slot.fill(0)
    slot["token"], slot["motion"], slot["terms"], slot["action"], slot["once"] = token, motion, len(condition.terms), \
        action.code, once
    if isinstance(action, MoveTo):
        target = np.asarray(action.target, dtype=float)
        if target.shape != (len(joint_names),) or not np.all(np.isfinite(target)):
            raise CommandRejected("MoveTo needs one finite position per joint", what=f"{len(joint_names)} positions",
                                  why=f"got {action.target!r}", how="pass the retract pose in joint order")
        slot["target"][:len(joint_names)] = target
    for k, term in enumerate(condition.terms):
        row = slot["term"][k]
        row["op"], row["measure"], row["threshold"] = term.op, term.measure, term.threshold
        comparison = term.measure != 0
        if term.measure == C["PLEM_MEASURE_DIGITAL_INPUT"] and isinstance(term.index, tuple):
            joint, bit = term.index
            row["index"] = _joint(joint, joint_names, "a reaction's quantity") * INPUT_BITS + bit
        elif comparison and term.measure not in (C["PLEM_MEASURE_WRENCH"], C["PLEM_MEASURE_MOTION_TIME"]):
            row["index"] = _joint(term.index, joint_names, "a reaction's quantity")  # type: ignore[arg-type]
        else:
            row["index"] = int(term.index)  # type: ignore[arg-type]


_ACTIONS: dict[int, type] = {C["PLEM_REACT_STOP"]: Stop, C["PLEM_REACT_HOLD"]: Hold,
                             C["PLEM_REACT_FREE_DRIVE"]: FreeDrive, C["PLEM_REACT_RECORD"]: Record}


def reaction_json(condition: Condition, action: Action) -> dict[str, object]:
    """A reaction as a request carries it (checked again by `reaction_from_json` where it arrives)."""
    condition = _condition(condition)
    return {"terms": [[t.op, t.measure, list(t.index) if isinstance(t.index, tuple) else t.index, t.threshold]
                      for t in condition.terms], "text": condition.text,
            "action": action.code, "target": list(action.target) if isinstance(action, MoveTo) else None}


def _index_of(measure: object, index: object) -> int | str | tuple[int | str, int] | None:
    """A request term's index: a joint (name or number), or for a digital input [joint, bit]; None when malformed."""
    def joint(value: object) -> bool:
        return isinstance(value, (int, str)) and not isinstance(value, bool)

    if measure == C["PLEM_MEASURE_DIGITAL_INPUT"]:
        if isinstance(index, list) and len(index) == 2 and joint(index[0]) and isinstance(index[1], int) \
                and not isinstance(index[1], bool) and 0 <= index[1] < INPUT_BITS:
            return index[0], index[1]
        return None
    return index if joint(index) else None  # type: ignore[return-value]


def reaction_from_json(value: object, max_text: int = 400) -> tuple[Condition, Action]:
    """The condition and action of a request's reaction, every part checked; CommandRejected names what is wrong."""
    if not isinstance(value, dict) or not isinstance(value.get("terms"), list) \
            or not 0 < len(value["terms"]) <= MAX_TERMS:
        raise CommandRejected("the reaction is malformed", what=f"1 to {MAX_TERMS} terms, an action and a text",
                              why=f"got {str(value)[:80]}", how="send reactions with robot.on() or until=")
    terms = []
    ops = {C[f"PLEM_TERM_{name}"] for name in ("ABOVE", "BELOW", "EQUAL", "AND", "OR", "NOT")}
    measures = {C[f"PLEM_MEASURE_{name}"] for name in ("POSITION", "VELOCITY", "EFFORT", "EXTERNAL_TORQUE", "WRENCH",
                                                       "FOLLOWING_ERROR", "MOTION_TIME", "DRIVE_STATE",
                                                       "DIGITAL_INPUT")}
    for term in value["terms"]:
        good = isinstance(term, list) and len(term) == 4 and term[0] in ops \
            and _index_of(term[1], term[2]) is not None \
            and isinstance(term[3], (int, float)) and not isinstance(term[3], bool) \
            and math.isfinite(term[3]) and (term[1] in measures or (term[1] == 0 and term[0] in ops - {
                C["PLEM_TERM_ABOVE"], C["PLEM_TERM_BELOW"], C["PLEM_TERM_EQUAL"]}))
        if not good:
            raise CommandRejected("a reaction term is malformed", what="[op, measure, joint, finite threshold]",
                                  why=f"got {str(term)[:80]}", how="send reactions with robot.on() or until=")
        terms.append(Term(int(term[0]), int(term[1]), _index_of(term[1], term[2]), float(term[3])))  # type: ignore[arg-type]
    text = value.get("text")
    code = value.get("action")
    if not isinstance(text, str) or len(text) > max_text or code not in ACTION_NAMES:
        raise CommandRejected("the reaction is malformed", what="a text and an action code",
                              why=f"text {str(text)[:40]!r}, action {code!r}", how="send reactions with robot.on()")
    action: Action = MoveTo(list(value.get("target") or [])) if code == C["PLEM_REACT_MOVE"] else _ACTIONS[code]()
    return Condition(tuple(terms), text), action
