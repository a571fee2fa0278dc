"""The band solvers against a dense solve: plain, and with rows of the identity left out
of the factorisation (the free contact probes)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pliant.models.banded import (
    band_factor_reduced,
    band_lu,
    band_lu_lapack,
    band_lu_solve,
    band_lu_solve_lapack,
    band_reduce,
    band_solve,
    band_solve_factored,
    band_solve_reduced,
    dense,
)


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


@settings(max_examples=80, deadline=None, derandomize=True)
@given(n=st.integers(1, 40), kl=st.integers(0, 6), ku=st.integers(0, 6),
       seed=st.integers(0, 2**31 - 1), share=st.floats(0.0, 0.9),
       fill=st.floats(0.05, 1.0))
def test_the_reduced_band_is_the_kept_submatrix_and_no_wider(n, kl, ku, seed, share,
                                                             fill):
    """A sparse band (most entries zero, as a KKT band is) without some rows and columns:
    the reduced band holds exactly the kept submatrix, its widths are the farthest kept
    nonzero's (found here by brute force), and one factorisation solves several
    right-hand sides."""
    rng = np.random.default_rng(seed)
    ab = random_band(rng, n, kl, ku)
    ab[:, : kl] = 0.0  # the fill rows stay empty
    ab *= rng.random(ab.shape) < fill
    for j in range(n):  # a nonzero diagonal (a singular kept part is another test)
        ab[j, kl + ku] = 3.0 + rng.random()
    drop = rng.random(n) < share
    for i in np.nonzero(drop)[0]:  # row i of the identity
        for j in range(max(0, i - kl), min(n, i + ku + 1)):
            ab[j, kl + ku + i - j] = 1.0 if i == j else 0.0
    A = dense(ab, kl, ku, n)
    keep = np.flatnonzero(~drop)
    sub = A[np.ix_(keep, keep)]
    c, lo, up, new = band_reduce(ab, kl, ku, drop)
    rows, cols = np.nonzero(sub)
    assert lo == max((rows - cols).max(initial=0), 0)
    assert up == max((cols - rows).max(initial=0), 0)
    assert np.array_equal(new[keep], np.arange(keep.size)) and np.all(new[drop] == -1)
    assert np.array_equal(dense(c, lo, up, keep.size), sub)
    factors = band_factor_reduced(ab, kl, ku, drop)
    assert factors[-1]
    for _ in range(2):
        b = rng.normal(size=n)
        x = band_solve_factored(ab, kl, ku, drop, *factors[:5], b)
        assert np.array_equal(x[drop], b[drop])
        assert np.allclose(A @ x, b, atol=1e-8 * np.linalg.cond(A))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(n=st.integers(1, 40), kl=st.integers(0, 6), ku=st.integers(0, 6),
       seed=st.integers(0, 2**31 - 1))
def test_lapack_and_the_hand_written_twin_agree(n, kl, ku, seed):
    """The dgbtf2 written out (over nonzero multipliers) and LAPACK's dgbtrf/dgbtrs:
    the same solution (to the matrix's conditioning), and both say so where a column
    vanishes or an entry is not a number."""
    rng = np.random.default_rng(seed)
    ab = random_band(rng, n, kl, ku)
    b = rng.normal(size=n)
    cond = np.linalg.cond(dense(ab, kl, ku, n))
    work, twin = ab.copy(), ab.copy()
    piv, ok = band_lu(work, kl, ku)
    piv_t, ok_t = band_lu_lapack(twin, kl, ku)
    if not (ok and ok_t):  # singular to round-off (a random draw can be: cond 2.5e14)
        assert cond > 1e12
        return
    x = band_lu_solve(work, piv, kl, ku, b)
    x_t = band_lu_solve_lapack(twin, piv_t, kl, ku, b)
    assert np.allclose(x, x_t, atol=1e-10 * cond * max(1.0, np.abs(x).max()))
    if n > 1:  # a zero column: singular, to both
        j = int(rng.integers(n))
        spoilt = ab.copy()
        spoilt[j, :] = 0.0
        assert not band_lu(spoilt.copy(), kl, ku)[1] and not band_lu_lapack(spoilt, kl, ku)[1]
    # An entry that is not a number, wherever it sits in the band: refused by both.
    j = int(rng.integers(n))
    i = int(rng.integers(max(0, j - ku), min(n, j + kl + 1)))
    for bad in (np.nan, np.inf):
        spoilt = ab.copy()
        spoilt[j, kl + ku + i - j] = bad
        assert not band_lu(spoilt.copy(), kl, ku)[1]
        assert not band_lu_lapack(spoilt.copy(), kl, ku)[1]


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


@settings(max_examples=60, deadline=None, derandomize=True)
@given(n=st.integers(4, 60), k=st.integers(1, 5), seed=st.integers(0, 2**31 - 1))
def test_the_lanczos_kernel_finds_the_smallest_eigenvalue_of_a_banded_pencil(n, k, seed):
    """softest_mode on a random symmetric band matrix A (indefinite) with a positive
    diagonal M, shifted below its spectrum, against scipy's dense generalized eigh."""
    from scipy.linalg import eigh

    from pliant.models.banded import band_lu
    from pliant.models.lanczos import softest_mode

    rng = np.random.default_rng(seed)
    k = min(k, n - 1)
    A = np.zeros((n, n))
    for d in range(k + 1):
        v = rng.normal(size=n - d)
        A += np.diag(v, d) + (np.diag(v, -d) if d else 0.0)
    w = rng.uniform(0.5, 2.0, size=n)
    exact = eigh(A, np.diag(w), eigvals_only=True)
    sigma = exact[0] - 1.0 - abs(exact[0])
    shifted = A - sigma * np.diag(w)
    ab = np.zeros((n, 3 * k + 1))
    for j in range(n):
        for i in range(max(0, j - k), min(n, j + k + 1)):
            ab[j, 2 * k + i - j] = shifted[i, j]
    piv, ok = band_lu(ab, k, k)
    assert ok
    theta, vector, converged, steps = softest_mode(ab, piv, k, k, np.arange(n), w,
                                                   rng.normal(size=n), 1e-12, n + 1)
    assert converged and steps <= n + 1
    assert sigma + 1.0 / theta == pytest.approx(exact[0], abs=1e-8 * (1 + abs(exact[0])))
    # Its vector is the mode: A v = lambda M v, M-normalised.
    lam = sigma + 1.0 / theta
    residual = A @ vector - lam * w * vector
    assert np.linalg.norm(residual) <= 1e-6 * (1 + np.abs(exact).max())
    assert vector @ (w * vector) == pytest.approx(1.0, rel=1e-9)
