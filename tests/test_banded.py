"""The band solvers against a dense solve: plain, and with rows of the identity left out
of the factorisation (the free contact probes)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pliant.models.banded import band_solve, band_solve_reduced, dense


def random_band(rng: np.random.Generator, n: int, kl: int, ku: int) -> np.ndarray:
    """A random band matrix in band layout, diagonally weak (so pivoting matters) but
    nonsingular with probability one."""
    ab = np.zeros((n, 2 * kl + ku + 1))
    for j in range(n):
        for i in range(max(0, j - ku), min(n, j + kl + 1)):
            ab[j, kl + ku + i - j] = rng.normal()
    return ab


@settings(max_examples=60, deadline=None, derandomize=True)
@given(n=st.integers(1, 40), kl=st.integers(0, 6), ku=st.integers(0, 6),
       seed=st.integers(0, 2**31 - 1))
def test_band_solve_matches_a_dense_solve(n, kl, ku, seed):
    rng = np.random.default_rng(seed)
    ab = random_band(rng, n, kl, ku)
    A = dense(ab, kl, ku, n)
    b = rng.normal(size=n)
    x, ok = band_solve(ab.copy(), kl, ku, b)
    assert ok
    assert np.allclose(A @ x, b, atol=1e-8 * np.linalg.cond(A))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(n=st.integers(2, 40), kl=st.integers(1, 6), ku=st.integers(1, 6),
       seed=st.integers(0, 2**31 - 1), share=st.floats(0.0, 0.9))
def test_identity_rows_leave_the_factorisation_and_the_answer_stays(n, kl, ku, seed,
                                                                    share):
    """Rows of the identity (their columns full) are known unknowns: the reduced solve
    gives the dense answer, leaves ``ab`` as it was, and the known ones equal their
    right-hand side."""
    rng = np.random.default_rng(seed)
    ab = random_band(rng, n, kl, ku)
    drop = rng.random(n) < share
    for i in np.nonzero(drop)[0]:  # row i of the identity
        for j in range(max(0, i - kl), min(n, i + ku + 1)):
            ab[j, kl + ku + i - j] = 1.0 if i == j else 0.0
    A = dense(ab, kl, ku, n)
    b = rng.normal(size=n)
    before = ab.copy()
    x, ok = band_solve_reduced(ab, kl, ku, b, drop)
    assert ok
    assert np.array_equal(ab, before)
    assert np.array_equal(x[drop], b[drop])
    assert np.allclose(A @ x, b, atol=1e-8 * np.linalg.cond(A))


def test_a_singular_remainder_is_reported():
    """Two equal rows among those kept: not solvable, and said so."""
    n, kl, ku = 4, 1, 1
    ab = np.zeros((n, 2 * kl + ku + 1))
    A = np.array([[1.0, 2.0, 0.0, 0.0], [1.0, 2.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
                  [0.0, 0.0, 3.0, 1.0]])
    for j in range(n):
        for i in range(max(0, j - ku), min(n, j + kl + 1)):
            ab[j, kl + ku + i - j] = A[i, j]
    drop = np.array([False, False, True, False])
    _, ok = band_solve_reduced(ab, kl, ku, np.ones(n), drop)
    assert not ok
