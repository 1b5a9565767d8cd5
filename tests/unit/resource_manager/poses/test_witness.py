"""Witnesses of a position: the one that disagrees with the rest is refused; blame names who placed it."""

from __future__ import annotations

import pytest

from resource_manager.poses.witness import Estimate, Reference, blame, consistent


def _e(o: str, x: float, y: float, s: float = 0.05) -> Estimate:
    return Estimate(o, x, y, s)


@pytest.mark.parametrize(
    ("estimates", "reference", "refused"),
    [
        ([_e("a", 3, 1), _e("b", 3.02, 1), _e("c", 2.99, 1.01)], None, []),  # all agree
        ([_e("a", 3, 1), _e("b", 3.02, 1), _e("liar", 3.6, 1.5)], None, ["liar"]),  # one of three lies
        ([_e("a", 3, 1), _e("liar", 3.6, 1.5)], None, []),  # two disagree, nothing to tell which: both kept
        ([_e("a", 3, 1), _e("liar", 3.6, 1.5)], Reference(3.01, 1.0, 0.03), ["liar"]),  # ...history tells
    ],
)
def test_the_witness_that_disagrees_with_the_rest_is_refused(
    estimates: list[Estimate], reference: Reference | None, refused: list[str]
) -> None:
    kept, out = consistent(estimates, 3.0, reference)
    assert out == refused
    assert {e.observer for e in kept} == {e.observer for e in estimates} - set(refused)


def test_blame_names_the_witnesses_off_the_reference_or_the_target_itself() -> None:
    ref = Reference(3.0, 1.0, 0.03)
    assert blame([_e("a", 3.01, 1.0), _e("liar", 3.6, 1.5)], "r1", ref, 3.0) == ["liar"]
    assert blame([_e("a", 3.2, 1.0), _e("b", 3.2, 1.0)], "r1", ref, 3.0) == ["a", "b"]  # only their mean is off
    assert blame([], "r1", ref, 3.0) == ["r1"]  # placed by its own sightings (resection)
