"""A payload held at the arm's flange, its checks, and the last body's inertia with it rigidly added.

A payload is a mass, its centre of mass in the flange frame (the arm's last link, as UR's `setPayload` and
franky take it) and optionally its rotational inertia about that centre; without one it is a point mass. The
same rules check it wherever it comes from (`robot.set_payload`, the launch argument `payload:=`, a robot
profile), so a payload the arm cannot carry is refused before any gravity model uses it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from plem.errors import ConfigError

#: Heaviest payload accepted (kg): far above what the 6- and 7-axis arms plem drives carry (Indy7: 7 kg), so a
#: real payload is never refused, while a unit mistake (grams for kilograms) is.
MAX_PAYLOAD_MASS = 100.0
#: Farthest centre of mass from the flange accepted (m): beyond any tool of an arm of about a metre's reach.
MAX_PAYLOAD_DISTANCE = 2.0
#: Relative tolerance of the inertia checks (symmetry, positive semi-definite, triangle inequality), so that
#: values rounded to a few digits, as CAD tools print them, pass.
INERTIA_TOLERANCE = 1e-6
#: Where each of a payload's fields can be set, for the HOW of its errors.
PAYLOAD_INTERFACES = ("robot.set_payload(mass, center_of_mass, inertia)", "the launch argument "
                      "payload:=mass,x,y,z[,ixx,ixy,ixz,iyy,iyz,izz]", "the profile's \"payload\" field")

PAYLOAD_RULES = (f"a mass from 0 to {MAX_PAYLOAD_MASS:g} kg, a centre of mass (m, in the flange frame) at most "
                 f"{MAX_PAYLOAD_DISTANCE:g} m from the flange, and an optional inertia about the centre of mass "
                 "(kg·m²): symmetric, positive semi-definite, each principal moment at most the sum of the two "
                 "others; every number finite")


def inertia_matrix(ixx: float, ixy: float, ixz: float, iyy: float, iyz: float, izz: float) -> np.ndarray:
    """The 3×3 inertia from its six values in the URDF's `<inertia>` order."""
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)


def _matrix_problems(inertia: np.ndarray) -> list[str]:
    """Why `inertia` (a finite 3×3 array) is no rigid body's inertia about its centre of mass; empty when it is."""
    scale = max(float(np.abs(inertia).max()), 1e-12)
    tolerance = INERTIA_TOLERANCE * scale
    if np.abs(inertia - inertia.T).max() > tolerance:
        return ["the inertia is not symmetric (ixy, ixz, iyz must equal iyx, izx, izy)"]
    moments = np.linalg.eigvalsh(inertia)
    if moments[0] < -tolerance:
        return [f"the inertia is not positive semi-definite (a principal moment is {moments[0]:.6g} kg·m²)"]
    if moments[0] + moments[1] < moments[2] - tolerance:
        return [f"the principal moments {', '.join(f'{m:.6g}' for m in moments)} kg·m² break the triangle "
                "inequality (each at most the sum of the two others): no rigid body has them"]
    return []


def payload_problems(mass: float, center_of_mass: Sequence[float] | np.ndarray,
                     inertia: Sequence[Sequence[float]] | np.ndarray | None) -> list[str]:
    """Every reason these values are not a payload plem accepts (`PAYLOAD_RULES`), empty when they are."""
    found: list[str] = []
    if not math.isfinite(mass) or not 0.0 <= mass <= MAX_PAYLOAD_MASS:
        found.append(f"mass {mass:g} kg is not between 0 and {MAX_PAYLOAD_MASS:g} kg")
    com = np.asarray(center_of_mass, dtype=float)
    if com.shape != (3,):
        found.append(f"the centre of mass has {com.size} values, not 3 (x, y, z)")
    elif not np.isfinite(com).all():
        found.append("the centre of mass is not finite")
    elif float(np.linalg.norm(com)) > MAX_PAYLOAD_DISTANCE:
        found.append(f"the centre of mass is {float(np.linalg.norm(com)):.6g} m from the flange, more than "
                     f"{MAX_PAYLOAD_DISTANCE:g} m")
    if inertia is not None:
        matrix = np.asarray(inertia, dtype=float)
        if matrix.shape != (3, 3):
            found.append(f"the inertia has shape {matrix.shape}, not 3×3")
        elif not np.isfinite(matrix).all():
            found.append("the inertia is not finite")
        else:
            found.extend(_matrix_problems(matrix))
    return found


@dataclass(frozen=True)
class Payload:
    """A rigid payload at the flange: mass (kg), centre of mass (m, flange frame), inertia about it (kg·m²; None
    for a point mass). Constructing one checks it: a ConfigError lists every problem."""

    mass: float
    center_of_mass: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[tuple[float, float, float], ...] | None = None

    def __post_init__(self) -> None:
        try:
            mass = float(self.mass)
            com = np.asarray(self.center_of_mass, dtype=float).reshape(-1)
            inertia = None if self.inertia is None else np.asarray(self.inertia, dtype=float)
        except (TypeError, ValueError, OverflowError) as error:
            raise self.refused(f"not numbers: {error}") from None
        problems = payload_problems(mass, com, inertia)
        if problems:
            raise self.refused("; ".join(problems))
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "center_of_mass", (float(com[0]), float(com[1]), float(com[2])))
        if inertia is not None:
            symmetric = (inertia + inertia.T) / 2
            object.__setattr__(self, "inertia", tuple(tuple(float(v) for v in row) for row in symmetric))

    @staticmethod
    def refused(why: str) -> ConfigError:
        """The error for an invalid payload, found `why`."""
        return ConfigError("invalid payload", what=PAYLOAD_RULES, why=why,
                           how="give a payload that meets these rules through " + ", ".join(PAYLOAD_INTERFACES))

    @classmethod
    def from_numbers(cls, values: Sequence[float]) -> Payload:
        """A payload from 4 numbers (mass, com x, y, z) or 10 (and ixx, ixy, ixz, iyy, iyz, izz as in a URDF)."""
        if len(values) not in (4, 10):
            raise cls.refused(f"{len(values)} numbers: a payload is 4 (mass, x, y, z) or 10 (and ixx, ixy, ixz, "
                              "iyy, iyz, izz)")
        inertia = inertia_matrix(*values[4:]) if len(values) == 10 else None
        return cls(values[0], (values[1], values[2], values[3]), None if inertia is None else inertia.tolist())

    @property
    def com(self) -> np.ndarray:
        """The centre of mass as a new array (m, flange frame)."""
        return np.array(self.center_of_mass)

    @property
    def inertia_about_com(self) -> np.ndarray:
        """The rotational inertia about the centre of mass as a new 3×3 array; zeros for a point mass."""
        return np.zeros((3, 3)) if self.inertia is None else np.array(self.inertia)


def combined_body(mass: float, com: np.ndarray, inertia: np.ndarray,
                  payload: Payload) -> tuple[float, np.ndarray, np.ndarray]:
    """A body's mass, centre of mass and inertia about it (`com`, `inertia` in the body's frame) with `payload`,
    given in the same frame, rigidly added: the masses sum, the centre is their mean, and each inertia moves to
    the new centre by the parallel-axis theorem. A body and payload of no mass stay the body as it was."""
    total = mass + payload.mass
    if total <= 0.0:
        return mass, np.array(com, dtype=float), np.array(inertia, dtype=float)
    centre = (mass * np.asarray(com, dtype=float) + payload.mass * payload.com) / total

    def moved(part_mass: float, part_com: np.ndarray) -> np.ndarray:
        offset = part_com - centre
        return part_mass * (float(offset @ offset) * np.eye(3) - np.outer(offset, offset))

    combined = (np.asarray(inertia, dtype=float) + moved(mass, np.asarray(com, dtype=float))
                + payload.inertia_about_com + moved(payload.mass, payload.com))
    return total, centre, combined
