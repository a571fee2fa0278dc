"""The Runge-Kutta tableau read from scipy satisfies the order conditions it claims."""

import numpy as np

from pliant.models.elastica2d.tableau import ORDER, dop853


def test_quadrature_order_conditions():
    _a, b, c = dop853()
    # sum_i b_i c_i^(q-1) = 1/q for q = 1..8: exact for polynomials of degree 7.
    for q in range(1, ORDER + 1):
        assert abs(b @ c ** (q - 1) - 1.0 / q) < 1e-14, q


def test_row_sums_are_the_nodes():
    a, _b, c = dop853()
    assert np.allclose(a.sum(axis=1), c, atol=1e-14)
    assert np.allclose(np.triu(a), 0.0)  # explicit
