"""Piecewise-polynomial motions: the one form in which every planned motion reaches the loop.

A motion is a table of knot times and, per segment and joint, the coefficients of a polynomial of
degree ORDER-1 in the time since the segment's start. The compiled core samples it in place (the table may
live in shared memory written by another process), so building a `PolynomialMotion` copies nothing and
costs the same for two points or five thousand. Splines of JointTrajectories are fitted into this form
directly; ruckig's jerk-limited motions are converted exactly (they are cubic between their phase
boundaries).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from plem.control import compiled

#: Coefficients per segment and joint, lowest order first: enough for a quintic (the core's PLEM_ORDER).
ORDER: int = compiled.ORDER
#: Knots closer than this (s) are one knot.
KNOT_RESOLUTION = 1e-9


def hermite_coefficients(duration: np.ndarray, p0: np.ndarray, p1: np.ndarray, v0: np.ndarray, v1: np.ndarray,
                         a0: np.ndarray, a1: np.ndarray, degree: np.ndarray) -> np.ndarray:
    """Per-segment coefficients (segments, ORDER, dof) joining the end states: linear, cubic or quintic.

    `duration` is (segments, 1); `degree` (segments,) holds 1, 3 or 5 per segment: positions only, positions
    and velocities, or positions, velocities and accelerations are matched at both ends.
    """
    step = p1 - p0
    linear, cubic, quintic = degree == 1, degree == 3, degree == 5
    c = np.zeros((len(duration), ORDER, p0.shape[1]))
    c[:, 0] = p0
    c[linear, 1] = (step / duration)[linear]
    c[~linear, 1] = v0[~linear]
    c[cubic, 2] = ((3 * step - (2 * v0 + v1) * duration) / duration**2)[cubic]
    c[cubic, 3] = ((-2 * step + (v0 + v1) * duration) / duration**3)[cubic]
    c[quintic, 2] = (a0 / 2)[quintic]
    c[quintic, 3] = ((20 * step - (12 * v0 + 8 * v1) * duration - (3 * a0 - a1) * duration**2)
                     / (2 * duration**3))[quintic]
    c[quintic, 4] = ((-30 * step + (16 * v0 + 14 * v1) * duration + (3 * a0 - 2 * a1) * duration**2)
                     / (2 * duration**4))[quintic]
    c[quintic, 5] = ((12 * step - 6 * (v0 + v1) * duration - (a0 - a1) * duration**2) / (2 * duration**5))[quintic]
    return c


def derivative_stack(coefficients: np.ndarray) -> np.ndarray:
    """Coefficients of the 0th to 4th time derivative, stacked: (5, segments, ORDER, dof)."""
    stack = [coefficients]
    for _ in range(4):
        derivative = np.zeros_like(coefficients)
        derivative[:, :-1] = stack[-1][:, 1:] * np.arange(1, ORDER)[:, None]
        stack.append(derivative)
    return np.stack(stack)


def extrema(coefficients: np.ndarray, durations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest value of each polynomial row (lowest order first) on [0, its duration].

    The candidates are both ends and the real stationary points inside, found for all rows at once as
    eigenvalues of companion matrices, grouped by the derivative's degree.
    """
    count, size = coefficients.shape
    scaled = coefficients * durations[:, None] ** np.arange(size)  # in s = t / duration, s in [0, 1]
    slope = scaled[:, 1:] * np.arange(1, size)
    magnitude = np.abs(slope)
    significant = magnitude > 1e-12 * magnitude.max(axis=1, keepdims=True)
    degree = np.where(significant.any(axis=1), size - 2 - np.argmax(significant[:, ::-1], axis=1), 0)
    points = np.full((count, size), np.nan)
    points[:, 0], points[:, 1] = 0.0, 1.0
    for d in range(1, size - 1):
        rows = np.flatnonzero(degree == d)
        if not rows.size:
            continue
        monic = slope[rows, :d] / slope[rows, d:d + 1]
        companion = np.zeros((rows.size, d, d))
        companion[:, np.arange(1, d), np.arange(d - 1)] = 1.0
        companion[:, :, -1] = -monic
        roots = np.linalg.eigvals(companion)
        inside = (np.abs(roots.imag) < 1e-6) & (roots.real > 0.0) & (roots.real < 1.0)
        points[rows, 2:2 + d] = np.where(inside, roots.real, np.nan)
    powers = points[:, :, None] ** np.arange(size)
    values = np.einsum("rcp,rp->rc", np.nan_to_num(powers), scaled)
    values[np.isnan(points)] = np.nan
    return np.nanmin(values, axis=1), np.nanmax(values, axis=1)


def segment_ranges(derivatives: np.ndarray, durations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per derivative order 0-3, segment and joint, the lowest and highest value: two (4, segments, dof) arrays."""
    segments, dof = derivatives.shape[1], derivatives.shape[3]
    rows = derivatives[:4].transpose(0, 1, 3, 2).reshape(4 * segments * dof, ORDER)
    low, high = extrema(rows, np.tile(np.repeat(durations, dof), 4))
    return low.reshape(4, segments, dof), high.reshape(4, segments, dof)


#: Samples per segment from which a motion's velocity peak is bounded (`PolynomialMotion.peaks`).
PEAK_SAMPLES = 17


class PolynomialMotion:
    """A motion sampled from knot times and coefficient arrays, which it views without copying.

    `knots` is (n+1,), `coefficients` (n, ORDER, dof) and `final` (3, dof): position, velocity and
    acceleration after the last knot. With n = 0 the motion is already at `final`.
    """

    def __init__(self, knots: np.ndarray, coefficients: np.ndarray, final: np.ndarray) -> None:
        self.knots = np.ascontiguousarray(knots, dtype=float)            # views stay views: already contiguous
        self.coefficients = np.ascontiguousarray(coefficients, dtype=float)
        self.segments = len(coefficients)
        self.duration = float(knots[-1]) if self.segments else 0.0
        final = np.array(final, dtype=float)  # a private copy: the settle check reads it after the table is reused
        final.flags.writeable = False
        self.final_positions, self.final_velocities, self.final_accelerations = final
        self._final = final
        self._dof = final.shape[1]
        self._cursor = np.zeros(1, dtype=np.int32)  # the segment of the last sample, kept by the core

    def sample(self, t: float, out: np.ndarray) -> bool:
        """Write position, velocity and acceleration `t` s after activation into the rows of `out` (3, dof);
        True once the motion is over. The core's sampling, stepping on from the last sample's segment."""
        done: bool = compiled.core.motion_sample(self.knots, self.coefficients, self._final, self.segments,
                                                 self._dof, t, self._cursor, out)
        return done

    def peaks(self) -> np.ndarray:
        """The largest |velocity|, |acceleration| and |jerk| of each joint along the motion, (3, dof): what the speed
        override must leave room for when it scales the motion (see plem_override). Per segment, the jerk (a
        quadratic) peaks at its ends or vertex and the acceleration (a cubic) at its ends or where the jerk is zero,
        exactly; the velocity at most its largest of PEAK_SAMPLES samples plus the acceleration's peak times half their
        spacing."""
        if self.segments == 0:
            at_rest: np.ndarray = np.vstack([np.abs(self._final[1]), np.abs(self._final[2]), np.zeros(self._dof)])
            return at_rest
        c = self.coefficients                          # (segments, ORDER, dof), lowest order first
        span = np.diff(self.knots)[:, None]            # (segments, 1)
        c2, c3, c4, c5 = c[:, 2], c[:, 3], c[:, 4], c[:, 5]
        qa, qb, qc = 60.0 * c5, 24.0 * c4, 6.0 * c3    # jerk = qa·t² + qb·t + qc
        with np.errstate(divide="ignore", invalid="ignore"):
            root = np.sqrt(np.maximum(qb * qb - 4.0 * qa * qc, 0.0))
            quadratic = np.abs(qa) > 1e-300
            roots = [np.where(quadratic, (-qb + root) / (2.0 * qa), np.where(qb != 0.0, -qc / qb, 0.0)),
                     np.where(quadratic, (-qb - root) / (2.0 * qa), 0.0),
                     np.where(quadratic, -qb / (2.0 * qa), 0.0)]   # the jerk's zeros, and its vertex
        times = [np.zeros_like(c2), np.broadcast_to(span, c2.shape)] + [np.clip(r, 0.0, span) for r in roots]

        def acceleration(t: np.ndarray) -> np.ndarray:
            value: np.ndarray = np.abs(2.0 * c2 + 6.0 * c3 * t + 12.0 * c4 * t * t + 20.0 * c5 * t ** 3)
            return value

        def jerk(t: np.ndarray) -> np.ndarray:
            value: np.ndarray = np.abs(qc + qb * t + qa * t * t)
            return value

        segment_acceleration = np.max([acceleration(t) for t in times[:4]], axis=0)
        peak_jerk = np.max([jerk(t) for t in (times[0], times[1], times[4])], axis=0).max(axis=0)
        fractions = np.linspace(0.0, 1.0, PEAK_SAMPLES)[:, None, None]
        t = fractions * span[None]                     # (samples, segments, 1)
        velocity = np.abs(c[:, 1] + 2.0 * c2 * t + 3.0 * c3 * t * t + 4.0 * c4 * t ** 3 + 5.0 * c5 * t ** 4)
        segment_velocity = velocity.max(axis=0) + segment_acceleration * span / (2.0 * (PEAK_SAMPLES - 1))
        peaks: np.ndarray = np.vstack([np.maximum(segment_velocity.max(axis=0), np.abs(self._final[1])),
                                       np.maximum(segment_acceleration.max(axis=0), np.abs(self._final[2])), peak_jerk])
        return peaks

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at `t` as new arrays, without touching the sampling cursor."""
        out = np.empty((3, self._dof))
        compiled.core.motion_sample(self.knots, self.coefficients, self._final, self.segments, self._dof,
                                    max(t, 0.0), np.zeros(1, dtype=np.int32), out)
        return out[0], out[1], out[2]


def _ruckig_knots(trajectory: Any) -> list[float]:  # a ruckig.Trajectory: ruckig ships no types
    """Every phase boundary of every joint of a ruckig trajectory, merged: between two, each joint is a cubic."""
    duration = float(trajectory.duration)
    times = [0.0, duration]
    offset = 0.0
    for section, profiles in enumerate(trajectory.profiles):
        for profile in profiles:
            t = offset
            for phase in (*profile.brake.t, *profile.t, *profile.accel.t):
                t += phase
                times.append(t)
        offset = float(trajectory.intermediate_durations[section])
    knots: list[float] = []
    for t in sorted(min(max(t, 0.0), duration) for t in times):
        if not knots or t - knots[-1] > KNOT_RESOLUTION:
            knots.append(t)
    if duration - knots[-1] > 0.0:
        knots[-1] = duration
    return knots


def from_ruckig(trajectory: Any, dof: int) -> PolynomialMotion:
    """The ruckig trajectory as a piecewise polynomial, exact: a cubic per joint between phase boundaries.

    Each piece is the Taylor cubic from the state at its start with the phase's constant jerk, which stays
    well conditioned for the microsecond phases ruckig produces (a Hermite fit would divide by T⁵).
    """
    knots = _ruckig_knots(trajectory)
    states = np.array([[np.asarray(v, dtype=float) for v in trajectory.at_time(t)]
                       for t in knots]).reshape(len(knots), 3, dof)
    final = states[-1]
    if len(knots) < 2:
        return PolynomialMotion(np.array([0.0]), np.zeros((0, ORDER, dof)), final)
    times = np.array(knots)
    coefficients = np.zeros((len(knots) - 1, ORDER, dof))
    coefficients[:, 0], coefficients[:, 1], coefficients[:, 2] = states[:-1, 0], states[:-1, 1], states[:-1, 2] / 2
    coefficients[:, 3] = np.diff(states[:, 2], axis=0) / (6 * np.diff(times)[:, None])
    return PolynomialMotion(times, coefficients, final)
