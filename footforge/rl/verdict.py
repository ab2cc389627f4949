"""Does a policy walk? The walking verdict of a rollout, from what the robots did rather than from
the return: forward tracking error, how long they stay up, how high the base rides and how each
foot shares the ground.

Verdict (one of VERDICTS):
- falls: the robots stay up less than MIN_UPTIME of the rollout on average;
- walks: forward error <= MAX_FORWARD_ERROR_MPS, up >= MIN_UPTIME, base >= MIN_BASE_HEIGHT_M, and
  every foot on the ground between MIN_STANCE and MAX_STANCE of the time while the planar command
  is at least MOVING_COMMAND_MPS (no three-legged hobble, no shuffle that never lifts a foot);
- stands: anything else (the reason names the first criterion missed).

Gait, from the feet's contact phases while commanded to move: the share of steps in which two feet
are in the same state (both on the ground or both in the air), for the diagonal, lateral (front,
hind) and same-side pairs. A trot moves diagonal pairs together, a pace same-side pairs, a bound
front and hind pairs; a gait with each foot stepping and no pair locked is four-beat (a walk's
footfall, or an irregular one).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from footforge.constants import LEGS

VERDICTS = ("walks", "stands", "falls")
MAX_FORWARD_ERROR_MPS = 0.25
"""Mean |vx command - vx| over the standing robots' steps, m/s (standing still scores the mean |vx
command|: 0.6 under a fixed 0.6 m/s, 0.5 under U(-1, 1))."""
MIN_UPTIME = 0.9
"""Mean share of the rollout a robot stays up (900 of 1,000 steps of a 20 s episode)."""
MIN_BASE_HEIGHT_M = 0.45
"""Mean base height over the ground, m (ANYmal C stands at about 0.52-0.55 m; a crouch is lower)."""
MIN_STANCE, MAX_STANCE = 0.2, 0.9
"""Each foot's share of the moving steps on the ground: below, the foot is held up; above, it
never leaves the ground."""
MOVING_COMMAND_MPS = 0.3
"""Steps whose planar command |v_xy| is at least this count as commanded to move, m/s."""
PAIR_LOCKED = 0.75
"""Two feet whose contact states agree on at least this share of the moving steps move together."""

PAIRS = {
    "diagonal": (("LF", "RH"), ("RF", "LH")),
    "lateral": (("LF", "RF"), ("LH", "RH")),
    "same_side": (("LF", "LH"), ("RF", "RH")),
}


@dataclass(frozen=True)
class WalkingVerdict:
    verdict: str
    """One of VERDICTS."""
    reason: str
    """Why, in a few words (for a stands or falls: the first criterion missed)."""
    gait: str
    """trot, pace, bound, four-beat (each foot stepping, no pair locked), stand (no foot steps) or
    none (no moving steps to judge)."""
    forward_error_mps: float
    """Mean |vx command - vx| over the standing robots' steps, m/s."""
    uptime: float
    """Mean share of the rollout the robots stayed up (1.0: none fell)."""
    base_height_m: float
    """Mean base height over the standing robots' steps, m."""
    stance_fraction: dict
    """Each foot (LF, RF, LH, RH): share of the moving steps on the ground."""
    pair_agreement: dict
    """diagonal, lateral, same_side: mean share of the moving steps in which the pair's feet are in
    the same contact state."""
    vx_slope: float
    """Least-squares slope of the measured vx on the commanded vx over the standing robots' steps
    (1: tracks, 0: ignores the command; NaN if the command never varies)."""

    def line(self) -> str:
        """One line for a card or a terminal, e.g. 'walks: trot, forward error 0.09 m/s'."""
        if self.verdict == "walks":
            return f"walks: {self.gait}, forward error {self.forward_error_mps:.2f} m/s"
        return f"{self.verdict}: {self.reason}"

    def to_dict(self) -> dict:
        return asdict(self)


def judge(contacts, up, base_height_m, command_vx, vx, command_xy_speed) -> WalkingVerdict:
    """The verdict of a rollout of R robots over T policy steps.

    Args:
      contacts: (R, T, 4) bool, each foot (LEGS order) on the ground after the step.
      up: (R, T) bool, the robot has not fallen by the end of the step (once False, stays False).
      base_height_m: (R, T) base height over the ground, m.
      command_vx, vx: (R, T) commanded and measured forward velocity in the base frame, m/s.
      command_xy_speed: (R, T) planar command |v_xy|, m/s.
    """
    contacts = np.asarray(contacts, bool)
    up = np.asarray(up, bool)
    base_height_m, command_vx, vx, speed = (
        np.asarray(a, float) for a in (base_height_m, command_vx, vx, command_xy_speed)
    )
    uptime = float(up.mean())
    forward_error = _mean(np.abs(command_vx - vx), up)
    height = _mean(base_height_m, up)
    moving = up & (speed >= MOVING_COMMAND_MPS)
    stance = {leg: _mean(contacts[..., i], moving) for i, leg in enumerate(LEGS)}
    agreement = {}
    for kind, pairs in PAIRS.items():
        same = [contacts[..., LEGS.index(a)] == contacts[..., LEGS.index(b)] for a, b in pairs]
        agreement[kind] = float(np.mean([_mean(s, moving) for s in same]))
    slope = _slope(command_vx[up], vx[up])
    gait = _gait(stance, agreement)
    if uptime < MIN_UPTIME:
        verdict, reason = "falls", f"up {uptime:.0%} of the time (walking: {MIN_UPTIME:.0%})"
    elif not np.isfinite(forward_error) or forward_error > MAX_FORWARD_ERROR_MPS:
        verdict, reason = "stands", f"forward error {forward_error:.2f} m/s (walking: {MAX_FORWARD_ERROR_MPS} or less)"
    elif height < MIN_BASE_HEIGHT_M:
        verdict, reason = "stands", f"crouched: base at {height:.2f} m (walking: {MIN_BASE_HEIGHT_M} m or more)"
    elif not moving.any():
        verdict, reason = "stands", f"never commanded {MOVING_COMMAND_MPS} m/s or more: gait not judged"
    else:
        low = [leg for leg, s in stance.items() if s < MIN_STANCE]
        high = [leg for leg, s in stance.items() if s > MAX_STANCE]
        if low:
            verdict, reason = "stands", "hobbles: " + ", ".join(f"{leg} on the ground {stance[leg]:.0%}" for leg in low)
        elif high:
            verdict, reason = (
                "stands",
                "shuffles: " + ", ".join(f"{leg} never lifts ({stance[leg]:.0%} on the ground)" for leg in high),
            )
        else:
            verdict, reason = "walks", f"{gait}, every foot steps"
    return WalkingVerdict(verdict, reason, gait, forward_error, uptime, height, stance, agreement, slope)


def _gait(stance: dict, agreement: dict) -> str:
    values = list(stance.values())
    if not values or not np.all(np.isfinite(values)):
        return "none"
    if min(values) > MAX_STANCE:
        return "stand"
    names = {"diagonal": "trot", "same_side": "pace", "lateral": "bound"}
    kind = max(agreement, key=lambda k: agreement[k])
    if agreement[kind] >= PAIR_LOCKED and all(MIN_STANCE <= s <= MAX_STANCE for s in values):
        return names[kind]
    return "four-beat"


def _mean(values, where) -> float:
    where = np.asarray(where, bool)
    return float(np.asarray(values, float)[where].mean()) if where.any() else float("nan")


def _slope(x, y) -> float:
    x, y = np.asarray(x, float), np.asarray(y, float)
    if x.size < 2 or np.ptp(x) < 1e-9:
        return float("nan")
    x0 = x - x.mean()
    return float((x0 * (y - y.mean())).sum() / (x0 * x0).sum())
