"""The walking verdict (footforge.rl.verdict) on synthetic rollouts whose answer is known by
construction: a trot, a pace, a bound, a stand, a three-legged hobble and a fall."""

import numpy as np
import pytest

from footforge.rl.verdict import MAX_FORWARD_ERROR_MPS, judge

R, T, PERIOD = 4, 200, 20
LF, RF, LH, RH = range(4)


def _rollout(pattern, vx_gain=1.0, fall_at=None, height=0.52):
    """R robots for T steps, each foot on the ground where pattern(t)[foot]; robot r commanded
    0.4 + 0.1 r m/s forward and moving at vx_gain times that."""
    contacts = np.array([[pattern(t) for t in range(T)]] * R, bool)
    command = np.repeat((0.4 + 0.1 * np.arange(R))[:, None], T, axis=1)
    up = np.ones((R, T), bool)
    if fall_at is not None:
        up[:, fall_at:] = False
    return dict(
        contacts=contacts,
        up=up,
        base_height_m=np.full((R, T), height),
        command_vx=command,
        vx=vx_gain * command,
        command_xy_speed=command,
    )


def _phase(t):
    return (t % PERIOD) < PERIOD // 2


def trot(t):
    first = _phase(t)
    return [first, not first, not first, first]  # LF with RH, RF with LH


def pace(t):
    first = _phase(t)
    return [first, not first, first, not first]  # LF with LH, RF with RH


def bound(t):
    first = _phase(t)
    return [first, first, not first, not first]  # the front pair, then the hind pair


def test_a_trot_walks_and_is_named_a_trot():
    v = judge(**_rollout(trot))
    assert v.verdict == "walks" and v.gait == "trot"
    assert v.stance_fraction == {"LF": 0.5, "RF": 0.5, "LH": 0.5, "RH": 0.5}
    assert v.pair_agreement == {"diagonal": 1.0, "lateral": 0.0, "same_side": 0.0}
    assert v.forward_error_mps == 0.0 and v.uptime == 1.0
    assert v.line() == "walks: trot, forward error 0.00 m/s"


@pytest.mark.parametrize("pattern, gait", [(pace, "pace"), (bound, "bound")])
def test_pace_and_bound_are_told_from_a_trot(pattern, gait):
    assert judge(**_rollout(pattern)).gait == gait


def test_vx_slope_is_the_gain_of_the_measured_on_the_commanded_speed():
    # vx = 0.8 x command exactly: the least-squares slope is 0.8; the error is 0.2 x mean command (0.55).
    v = judge(**_rollout(trot, vx_gain=0.8))
    assert v.vx_slope == pytest.approx(0.8)
    assert v.forward_error_mps == pytest.approx(0.2 * 0.55)


def test_standing_still_under_a_forward_command_stands():
    v = judge(**_rollout(lambda t: [True] * 4, vx_gain=0.0))
    assert v.verdict == "stands" and v.gait == "stand"
    assert v.forward_error_mps == pytest.approx(0.55)  # the mean command: above MAX_FORWARD_ERROR_MPS
    assert v.forward_error_mps > MAX_FORWARD_ERROR_MPS
    assert "forward error" in v.reason


def test_a_foot_held_up_is_a_hobble_even_when_the_robot_tracks():
    v = judge(**_rollout(lambda t: trot(t)[:3] + [False]))
    assert v.verdict == "stands"
    assert v.stance_fraction["RH"] == 0.0
    assert v.reason == "hobbles: RH on the ground 0%"
    assert v.line() == "stands: hobbles: RH on the ground 0%"


def test_a_foot_that_never_lifts_is_a_shuffle():
    v = judge(**_rollout(lambda t: [True] + trot(t)[1:]))
    assert v.verdict == "stands" and v.reason.startswith("shuffles: LF never lifts")


def test_a_crouch_is_not_walking():
    v = judge(**_rollout(trot, height=0.40))
    assert v.verdict == "stands" and v.reason.startswith("crouched")


def test_robots_that_fall_early_fall():
    # Up for the first 60 of 200 steps (three whole gait periods): uptime 0.3; the trot before
    # the fall does not make it walk.
    v = judge(**_rollout(trot, fall_at=60))
    assert v.verdict == "falls" and v.uptime == pytest.approx(0.3)
    assert v.stance_fraction["LF"] == pytest.approx(0.5)  # measured on the 60 steps up


def test_no_moving_command_means_no_gait_judged():
    data = _rollout(trot)
    data["command_xy_speed"] = np.zeros((R, T))
    data["command_vx"] = data["vx"] = np.zeros((R, T))
    v = judge(**data)
    assert v.verdict == "stands" and v.gait == "none" and np.isnan(v.vx_slope)
