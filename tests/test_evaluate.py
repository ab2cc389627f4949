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


def test_command_changes_bin_each_new_command_and_the_falls_that_follow_it():
    """Three robots, 10 policy steps of 0.5 s, a 2-s window (4 steps): a full-speed reversal followed by a fall
    within the window, two small changes never followed by one (the second near the rollout's end), and a
    sideways change whose fall comes too late, then a second change that the same fall follows in time; the
    fresh command of a robot restarting as it goes down, and a change after it is down, are not changes."""
    import numpy as np

    from footforge.rl.evaluate import command_changes, command_falls_cell, fall_times, falls_after

    steps = 10
    command = np.zeros((3, steps, 2))
    command[0, :3] = [1.0, 0.0]
    command[0, 3:] = [-1.0, 0.0]  # step 3: reversal, |dv| = 2 m/s
    command[1, 3:] = [0.3, 0.0]  # step 3: 0.3 m/s
    command[1, 8:] = [0.3, 0.4]  # step 8: 0.4 m/s, the rollout's end within its window, the robot up to the end
    command[2, :] = [0.5, 0.0]
    command[2, 3:] = [0.5, 0.5]  # step 3: 0.5 m/s sideways
    command[2, 8:] = [1.0, 0.5]  # step 8: 0.5 m/s
    turn = np.zeros((3, steps))
    turn[0, 3], turn[1, 3], turn[1, 8], turn[2, 3], turn[2, 8] = -3.0, 0.1, 2.0, 1.0, 0.5
    alive = np.ones((3, steps), bool)
    alive[0, 5:] = False  # down after step 5: 1 s after its change
    alive[2, 9:] = False  # down after step 9: 3 s after its first change, 0.5 s after its second
    command[0, 5:] = [0.2, 0.2]  # the fresh command of a robot restarting as it goes down: not a change
    command[0, 7:] = [0.3, 0.2]  # a change while down: not counted
    result = command_changes(command, turn, alive, policy_dt=0.5, window_s=2.0)
    assert result["changes"] == 5 and result["fell"] == 2
    assert result["speed_change_from_mps"] == [0.0, 0.5, 1.0, 1.5]
    assert result["speed_change_changes"] == [2, 2, 0, 1] and result["speed_change_falls"] == [0, 1, 0, 1]
    assert result["turn_changes"] == [2, 1, 1, 1] and result["turn_falls"] == [1, 0, 0, 1]
    # falls_after's window (falls at (step + 1) dt, events at (change step + 1) dt), here without same-step falls.
    events = [(s + 1) * 0.5 for s in (3, 8)]
    assert len(falls_after(fall_times(alive, 0.5), events, 2.0)) == result["fell"]
    assert command_falls_cell({"command_changes": result}) == "<0.5 m/s 0/2, 0.5-1 1/2, 1-1.5 0/0, >=1.5 1/1"
    assert command_falls_cell({}) == "-"  # a result from before command_changes was recorded
