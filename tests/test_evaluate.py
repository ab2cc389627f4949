"""The evaluation's indices computed from constructed motions (footforge/rl/evaluate.py)."""

import pytest


def test_the_slippage_index_measures_a_foot_moved_by_a_known_distance():
    """A stance foot dragged 3 cm over a step in which the base travels 0.5 m counts 0.03 / 0.5; a foot
    that lifts off or lands within the step (in the air at one end) does not count; a fallen robot's
    steps count neither slip nor travel."""
    import numpy as np

    from footforge.rl.evaluate import foot_slip, slippage_index

    before = np.zeros((4, 2))
    after = before.copy()
    after[0] = [0.03, 0.0]  # LF dragged 3 cm, on the ground at both ends
    after[1] = [0.0, 0.20]  # RF swung 20 cm: lifts off before the step ends
    after[2] = [0.12, 0.0]  # LH lands during the step
    on_before = np.array([True, True, False, True])
    on_after = np.array([True, False, True, True])  # RH stays, unmoved
    slip = float(foot_slip(before, after, on_before, on_after))
    assert slip == pytest.approx(0.03, abs=1e-7)
    # Two robots x two steps; the second robot falls after its first step (its NaNs must not leak).
    slips = np.array([[slip, 0.01], [0.02, np.nan]])
    travel = np.array([[0.5, 0.25], [0.25, np.nan]])
    alive = np.array([[True, True], [True, False]])
    assert slippage_index(slips, travel, alive) == pytest.approx((0.03 + 0.01 + 0.02) / (0.5 + 0.25 + 0.25))
    assert np.isnan(slippage_index(slips, np.zeros_like(travel), alive))
