"""Reward terms declared once, each owning its parameters (footforge/envs/rewards.py, RewardConfig):
every term's value on a fixed state equals a direct numpy computation of its formula and the value
the code gave before the terms held their own parameters (recorded below), runs saved with the
old flat parameters load to the same values, and a term declared on one line flows through the
sum, config.json and the overrides."""

import json
from dataclasses import dataclass, replace

import jax.numpy as jp
import numpy as np
import pytest

from footforge import envs
from footforge.envs import rewards
from footforge.envs.config import EnvConfig, RewardConfig, RewardTerm
from footforge.errors import InputError
from footforge.rl import presets
from footforge.rl.config import env_config_from_dict, from_dict, to_dict

STATE = {
    "command": [0.6, -0.3, 0.4],
    "lin_vel": [0.45, -0.1, 0.07],
    "ang_vel": [0.2, -0.15, 0.25],
    "gravity": [0.05, -0.08, -0.995],
    "base_height": 0.47,
    "torques": [19.344, 20.294, -2.786, -31.702, 37.348, -14.34, -23.973, 28.621, 1.052, -25.661, 20.037, 23.438],
    "joint_vel": [0.323, 1.93, 0.665, -0.398, -1.138, 1.287, 2.413, -1.838, 0.661, -2.631, 0.306, -2.325],
    "last_joint_vel": [1.534, 2.726, 2.671, 1.324, 1.386, 1.182, 0.293, -1.254, -0.449, 2.414, 2.967, 2.107],
    "action": [0.337, -0.094, 0.297, 0.73, 0.884, 0.933, -0.968, 0.26, -0.528, -0.948, -0.898, 0.657],
    "last_action": [-0.146, -0.811, 0.891, -0.03, 0.44, 0.123, 0.089, 0.129, -0.49, -0.295, -0.654, 0.509],
    "haa_offset": [0.05, -0.12, 0.03, -0.02],
    "joint_offset": [-0.009, -0.001, -0.086, 0.279, 0.269, -0.037, -0.261, 0.262, 0.117, -0.061, 0.236, -0.273],
    "touchdown_air_time": [0.62, 0.0, 0.3, 0.0],
}
"""A step's quantities: moving command, two feet touching down (LF after 0.62 s, LH after 0.3 s)."""

BEFORE = {
    "lin_vel_xy": 0.7788007259368896,
    "yaw_rate": 0.9139311909675598,
    "lin_vel_z": 0.004900000058114529,
    "ang_vel_xy": 0.0625,
    "orientation": 0.008899999782443047,
    "base_height": 0.00249999831430614,
    "torques": 6403.60546875,
    "joint_acc": 73.71418762207031,
    "action_rate": 4.174753189086914,
    "hip": 0.2199999988079071,
    "feet_air_time": -0.07999998331069946,
    "stand_still": 0.0,
}
"""Each term of RewardConfig() on STATE, unscaled, as the code before this change computed it
(`term.compute(q, RewardConfig())`, commit 16a33bf)."""

BEFORE_STANDING = BEFORE | {"lin_vel_xy": 0.50661700963974, "feet_air_time": 0.0, "stand_still": 1.8910000324249268}
"""The same with the command (0.05, 0, 0.4): below stand_still's and feet_air_time's 0.1 m/s."""

BEFORE_OWN_PARAMETERS = BEFORE | {
    "lin_vel_xy": 0.8824968934059143,
    "yaw_rate": 0.9559974670410156,
    "base_height": 0.0004000004264526069,
    "feet_air_time": 0.3199999928474426,
}
"""RewardConfig(tracking_sigma=0.5, base_height_target_m=0.45, feet_air_time_target_s=0.3) before."""

BEFORE_FLAT_REWARD = 0.04371851556786447
"""The summed, weighted (x scale x 0.02 s) terms of envs.default_config("flat", "aof", "B") on STATE before."""


def _quantities(**changes) -> rewards.Quantities:
    return rewards.Quantities(**{k: jp.asarray(v, jp.float32) for k, v in (STATE | changes).items()})


def _numpy_terms(state: dict, sigma=0.25, target_m=0.52, target_s=0.5) -> dict[str, float]:
    """Each term's formula (envs.rewards' docstrings), written again in numpy."""
    s = {k: np.asarray(v, float) for k, v in state.items()}
    moving = np.hypot(*s["command"][:2]) > 0.1
    landed = s["touchdown_air_time"] > 0
    return {
        "lin_vel_xy": np.exp(-np.sum((s["command"][:2] - s["lin_vel"][:2]) ** 2) / sigma),
        "yaw_rate": np.exp(-((s["command"][2] - s["ang_vel"][2]) ** 2) / sigma),
        "lin_vel_z": s["lin_vel"][2] ** 2,
        "ang_vel_xy": np.sum(s["ang_vel"][:2] ** 2),
        "orientation": np.sum(s["gravity"][:2] ** 2),
        "base_height": (s["base_height"] - target_m) ** 2,
        "torques": np.sum(s["torques"] ** 2),
        "joint_acc": np.sum((s["joint_vel"] - s["last_joint_vel"]) ** 2),
        "action_rate": np.sum((s["action"] - s["last_action"]) ** 2),
        "hip": np.sum(np.abs(s["haa_offset"])),
        "feet_air_time": np.sum((s["touchdown_air_time"] - target_s) * landed) * moving,
        "stand_still": np.sum(np.abs(s["joint_offset"])) * (not moving),
    }


def _values(cfg: RewardConfig, q: rewards.Quantities) -> dict[str, float]:
    return {name: float(v) for name, v in rewards.unscaled(cfg, q).items()}


@pytest.mark.parametrize("command, before", [([0.6, -0.3, 0.4], BEFORE), ([0.05, 0.0, 0.4], BEFORE_STANDING)])
def test_every_term_on_a_fixed_state_is_its_formula_and_what_it_was(command, before):
    values = _values(RewardConfig(), _quantities(command=command))
    assert set(before) <= set(values)  # the terms of the recorded code are all still declared
    numpy_values = _numpy_terms(STATE | {"command": command})
    for name in before:
        assert values[name] == pytest.approx(before[name], rel=1e-6, abs=1e-9), name
        assert values[name] == pytest.approx(numpy_values[name], rel=1e-5, abs=1e-7), name


def test_the_weighted_sum_of_the_flat_task_is_what_it_was():
    cfg = envs.default_config("flat", "aof", "B")
    values = rewards.unscaled(cfg.rewards, _quantities())
    weighted = rewards.weighted(cfg.rewards, values, cfg.policy_dt)
    assert cfg.policy_dt == pytest.approx(0.02)
    assert float(sum(weighted.values())) == pytest.approx(BEFORE_FLAT_REWARD, rel=1e-6)
    scales = {name: term.scale for name, term in rewards.terms(cfg.rewards).items()}
    assert {name: float(v) for name, v in weighted.items()} == pytest.approx(
        {name: float(values[name]) * scales[name] * cfg.policy_dt for name in values}
    )


def test_runs_saved_with_the_flat_parameters_load_to_the_same_terms():
    """config.json before the terms held their parameters: tracking_sigma (both tracking terms),
    base_height_target_m, feet_air_time_target_s in "rewards", beside bare or {"scale"} terms."""
    saved = to_dict(EnvConfig())
    old_rewards = {
        name: {"scale": value["scale"]} for name, value in saved["rewards"].items() if isinstance(value, dict)
    }
    old_rewards |= {
        "tracking_sigma": 0.5,
        "base_height_target_m": 0.45,
        "feet_air_time_target_s": 0.3,
        "clip_total_at_zero": True,
        "fall": -1.0,
    }
    env = env_config_from_dict(json.loads(json.dumps({**saved, "rewards": old_rewards})))
    values = _values(env.rewards, _quantities())
    numpy_values = _numpy_terms(STATE, sigma=0.5, target_m=0.45, target_s=0.3)
    for name, value in BEFORE_OWN_PARAMETERS.items():
        assert values[name] == pytest.approx(value, rel=1e-6, abs=1e-9), name
        assert values[name] == pytest.approx(numpy_values[name], rel=1e-5, abs=1e-7), name
    assert env.rewards.lin_vel_xy.params == env.rewards.yaw_rate.params == {"sigma": 0.5}
    # Saved again, the run's configuration is in today's form and loads to itself.
    again = json.loads(json.dumps(to_dict(env)))
    assert again["rewards"]["base_height"] == {"scale": -10.0, "params": {"target_m": 0.45}}
    assert "tracking_sigma" not in again["rewards"] and env_config_from_dict(again) == env


def test_a_term_s_parameters_are_exactly_its_function_s():
    with pytest.raises(InputError, match=r"lin_vel_xy: parameters \[\] given, its function takes \['sigma'\]"):
        RewardTerm(rewards.lin_vel_xy, 1.0)
    with pytest.raises(InputError, match="its function takes"):
        RewardTerm(rewards.torques, 1.0, sigma=0.1)
    saved = to_dict(EnvConfig())
    saved["rewards"]["lin_vel_xy"]["params"] = {"sigmaa": 0.3}  # a misspelt parameter in a config.json
    with pytest.raises(InputError, match="sigmaa"):
        env_config_from_dict(saved)
    # A partial params object keeps the others' defaults; dataclasses.replace keeps the parameters.
    term = replace(RewardConfig().feet_air_time, scale=2.0)
    assert (term.scale, term.params) == (2.0, {"target_s": 0.5})
    assert hash(EnvConfig()) == hash(EnvConfig())  # configurations stay hashable


def _toy(q: rewards.Quantities, *, gain: float):
    """A term declared only in this test: gain x |command_xy|^2."""
    return gain * (q.command[:2] ** 2).sum()


@dataclass(frozen=True)
class _WithToy(RewardConfig):
    toy: RewardTerm = RewardTerm(_toy, -0.5, gain=3.0)


def test_a_term_declared_on_one_line_is_summed_saved_and_overridden():
    """What the environment (metrics `reward/<name>`, the sum), config.json and `--set` read all
    follow RewardConfig's fields: a function and one declaration make a term."""
    cfg = _WithToy()
    assert list(rewards.terms(cfg))[-1] == "toy"
    q = _quantities()
    values = rewards.unscaled(cfg, q)
    assert float(values["toy"]) == pytest.approx(3.0 * (0.6**2 + 0.3**2), rel=1e-6)
    assert float(rewards.weighted(cfg, values, 0.02)["toy"]) == pytest.approx(-0.5 * 0.02 * float(values["toy"]))
    saved = json.loads(json.dumps(to_dict(cfg)))
    assert saved["toy"] == {"scale": -0.5, "params": {"gain": 3.0}}
    assert from_dict(_WithToy, saved, _WithToy()) == cfg
    env = replace(EnvConfig(), rewards=cfg)
    env = presets._assign(env, ("rewards", "toy", "params", "gain"), "4", "env.rewards.toy.params.gain=4", "--set")
    assert env.rewards.toy.params == {"gain": 4.0} and env.rewards.toy.scale == -0.5
