"""PyElastica's localized helical buckling benchmark (a rod clamped at both ends, one
turned 27 times as they close in by 3 %), posed in pliant and matched against its
closed form: pliant's equilibrium followed from the published shape (``rod3d.
from_shape``) converges to it at second order. (A warm ramp from straight does not get
there: without self-contact the rod passes through itself, and most of its twist goes
into writhe, a lower state.)"""

from __future__ import annotations

import math

import numpy as np

import pliant as pl
from pliant.core.tube import rotation_minimizing_frames
from pliant.models import rod3d

from .helpers import localized_helix

B, C = 1.345, 0.789


def _answer(curve: np.ndarray, elements: int):
    """pliant's equilibrium from the closed form's shape: (T [N], M [N m], largest
    distance from the axis [m], verdict)."""
    turn = 27 * 2 * math.pi
    part = pl.Part(1.0, B, torsional_stiffness=C, axial_stiffness=1e8 * B)  # ~inextensible
    problem = pl.Problem(part, (
        pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(0, 0, 1), normal=(1, 0, 0)),
        pl.clamp(1.0, tuple(curve[-1]), tangent=(0, 0, 1),
                 normal=(math.cos(turn), math.sin(turn), 0.0), name="end")))
    # The sections turned so that the end's d1 has made the 27 turns: the rotation-
    # minimising frame's own turn at the end, made up to them.
    d1 = rotation_minimizing_frames(curve, np.array([1.0, 0.0, 0.0]))[-1][:, 0]
    eq = rod3d.from_shape(problem, curve, np.array([1.0, 0.0, 0.0]),
                          rod3d.RodSolver(elements=elements, settle=False),
                          twist=turn - math.atan2(d1[1], d1[0]))
    load = eq.loads["end"]
    radius = float(np.hypot(eq.position[:, 0], eq.position[:, 1]).max())
    return float(load.force[2]), float(load.moment[2]), radius, eq.verdict


def test_the_localized_helix_is_an_equilibrium_converging_to_the_closed_form():
    """From 400 to 800 elements the end tension and the end moment each come four times
    nearer the closed form (second order), the helix's amplitude nearer too, and the
    Richardson extrapolation of the two meets it: 0.2 % for the loads, 0.3 % for the
    amplitude (the closed form is the infinite rod's shape on the finite rod's loads).
    Each answer is stable or neutral (a turn about the chord costs nothing)."""
    curve, moment, tension, amplitude = localized_helix()
    assert abs(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum() - 1.0) < 1e-6
    coarse, fine = _answer(curve, 400), _answer(curve, 800)
    assert coarse[3] in ("stable", "neutral") and fine[3] in ("stable", "neutral")
    for k, exact in enumerate((tension, moment, amplitude)):
        error_coarse, error_fine = coarse[k] - exact, fine[k] - exact
        # (the amplitude's closed form is the infinite rod's: its error levels off)
        assert abs(error_coarse) > (3.0 if k < 2 else 2.0) * abs(error_fine), (
            k, coarse[k], fine[k], exact)
        extrapolated = fine[k] + (fine[k] - coarse[k]) / 3.0
        assert abs(extrapolated - exact) < (0.002 if k < 2 else 0.003) * abs(exact)
