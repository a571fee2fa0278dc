"""Features where they meet, two at a time (issue 61): the CI subset of
``tests/combinations.py``'s cases (``benchmarks/combinations.py`` runs them all and
prints counts per pair). Each is checked against a value pliant did not compute the same
way; none may be wrong, refused or rest on a fallback."""

from __future__ import annotations

import pytest

from .combinations import CASES, outcome

FAST = [c for c in CASES if c.fast]


@pytest.mark.parametrize("case", FAST, ids=[c.name.replace(" ", "-") for c in FAST])
def test_a_combination_of_features_gives_the_independent_answer(case, tmp_path,
                                                                 monkeypatch):
    monkeypatch.setenv("PLIANT_CACHE", str(tmp_path / "cache"))
    result = outcome(case, tmp_path)
    assert result.status == "right", f"{result.pair}: {result.status}: {result.detail}"


def test_the_ci_subset_covers_a_floor_of_the_pairs():
    """Every pair of the suite has a case in CI but those that take minutes (the
    benchmark runs them), and the subset is most of the suite."""
    pairs = {c.pair for c in CASES}
    assert len({c.pair for c in FAST}) >= len(pairs) - 1 and len(FAST) >= 0.7 * len(CASES)
