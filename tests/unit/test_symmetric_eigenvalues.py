"""The inertia check's eigenvalues agree with LAPACK's (numpy.linalg.eigvalsh) to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from plem.description.model import symmetric_eigenvalues

RNG = np.random.default_rng(7)


def symmetric(values: np.ndarray) -> list[list[float]]:
    return ((values + values.T) / 2).tolist()


def rotated(eigenvalues: list[float]) -> list[list[float]]:
    q, _ = np.linalg.qr(RNG.normal(size=(3, 3)))
    return (q @ np.diag(eigenvalues) @ q.T).tolist()


MATRICES = (
    [symmetric(RNG.uniform(-1, 1, size=(3, 3))) for _ in range(200)]
    + [symmetric(RNG.uniform(-1, 1, size=(3, 3)) * 10.0 ** RNG.uniform(-300, 300)) for _ in range(50)]
    + [rotated(values) for values in ([1.0, 1.0, 1.0], [1.0, 1.0, 2.0], [0.02, 0.02, -1e-12], [0.0, 0.0, 3.0])]
    + [[[0.0] * 3] * 3,
       [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
       [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
       [[0.1, 0.001, 0.002], [0.001, 0.2, 0.003], [0.002, 0.003, 0.15]],
       [[1.0, 1e-18, 0.0], [1e-18, 1.0, 0.0], [0.0, 0.0, 1.0]]]
)


@pytest.mark.parametrize("matrix", MATRICES)
def test_matches_lapack(matrix: list[list[float]]) -> None:
    ours = symmetric_eigenvalues(matrix)
    reference = np.linalg.eigvalsh(np.array(matrix))
    scale = max(abs(value) for row in matrix for value in row) or 1.0
    assert ours == sorted(ours)
    assert max(abs(a - b) for a, b in zip(ours, reference, strict=True)) <= 1e-14 * scale
