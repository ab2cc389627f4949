"""Flat-task training: hyperparameter checks, config round trip, a run killed with SIGKILL and
resumed from its last checkpoint, and the saved policy loaded for inference."""

import json
import os
import signal
import subprocess
import sys
import time

import jax
import jax.numpy as jp
import numpy as np
import pytest
from conftest import REPO

from footforge import envs
from footforge.envs.config import EnvConfig
from footforge.errors import InputError
from footforge.train import (
    PPOConfig,
    from_dict,
    latest_checkpoint,
    load_policy,
    to_dict,
)

TINY = ["--num-envs", "8", "--unroll-length", "4", "--batch-size", "8", "--minibatches", "1",
        "--eval-envs", "4", "--checkpoint-every", "32"]


def test_bad_hyperparameters_are_input_errors():
    with pytest.raises(InputError, match="not a multiple of num_envs"):
        PPOConfig(num_envs=100, batch_size=64, num_minibatches=1).check()
    with pytest.raises(InputError, match="num_envs must be positive"):
        PPOConfig(num_envs=0).check()


def test_configs_round_trip_through_json():
    env = envs.default_config("flat", "aof", "BH")
    assert from_dict(EnvConfig, json.loads(json.dumps(to_dict(env)))) == env
    ppo = PPOConfig(policy_hidden_layers=(8, 4))
    assert from_dict(PPOConfig, json.loads(json.dumps(to_dict(ppo)))) == ppo


def test_tiny_ppo_run_increases_the_return(built, tmp_path):
    """Brax PPO on the flat environment, 4 minutes on 2 CPU cores: the evaluation return must grow.

    The task is the paper's flat task made learnable in ~100k steps: zero commands, no pushes,
    no observation noise, no domain randomisation (tests/test_randomization.py covers it; each
    robot's own model makes compiling and stepping several times slower on the CPU), 2 s
    episodes and a small network. The untrained policy's mean actions integrate the targets away
    from the pose and the robot falls within ~0.35 s; PPO must learn to hold itself up, which
    lengthens episodes and raises the return. Deterministic: the seed fixes the figures.
    """
    from dataclasses import replace

    from footforge import train
    cfg = envs.default_config("flat", "ball", "B")
    cfg = replace(cfg, build_dir=str(built["ball"][0]), episode_length_s=2.0,
                  commands=replace(cfg.commands, lin_vel_x_range=(0.0, 0.0), lin_vel_y_range=(0.0, 0.0),
                                   heading_range=(0.0, 0.0)),
                  pushes=replace(cfg.pushes, enabled=False), observations=replace(cfg.observations, noise=False),
                  randomization=replace(cfg.randomization, friction_range=None))
    ppo = PPOConfig(num_envs=32, unroll_length=16, batch_size=32, num_minibatches=4, num_timesteps=98_304,
                    checkpoint_every_steps=32_768, num_eval_envs=32, policy_hidden_layers=(32, 32),
                    value_hidden_layers=(32, 32), learning_rate=1e-3, seed=0)
    train.train(cfg, ppo, tmp_path / "run")
    evaluations = [line for line in map(json.loads, (tmp_path / "run" / "metrics.jsonl").read_text().splitlines())
                   if "eval/episode_reward" in line]  # the other lines: training episodes' metrics
    curve = [(e["global_step"], e["eval/episode_reward"], e["eval/avg_episode_length"]) for e in evaluations]
    (_, first_return, first_length), (_, last_return, last_length) = curve[0], curve[-1]
    assert [c[0] for c in curve] == [0, 32_768, 65_536, 98_304]
    # The initial policy collapses in ~16 policy steps (0.3 s); after training it stands longer.
    assert first_length < 25 and last_length > 1.5 * first_length, curve
    assert last_return > 1.5 * first_return, curve


def _train(out, build_dir, timesteps, *extra):
    return [sys.executable, str(REPO / "pipelines/train_flat.py"), "--feet", "ball", "--build-dir", str(build_dir),
            "--timesteps", str(timesteps), "--out", str(out), *TINY, *extra]


@pytest.fixture(scope="module")
def resumed(built, tmp_path_factory):
    """A tiny run killed with SIGKILL after its second checkpoint, then resumed: (run dir, step at the kill)."""
    out = tmp_path_factory.mktemp("train") / "run"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(_train(out, built["ball"][0], 100_000), env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 600
    while time.time() < deadline and (latest_checkpoint(out) is None or latest_checkpoint(out)[0] < 64):
        assert proc.poll() is None, "training stopped before its second checkpoint"
        time.sleep(1)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    killed_at, _ = latest_checkpoint(out)
    assert not (out / "policy").exists()
    # Resume with the same options and a total just past the checkpoint: it must continue, not restart.
    done = subprocess.run(_train(out, built["ball"][0], killed_at + 64, "--resume"), env=env,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return out, killed_at


@pytest.mark.slow  # the resumed run (a real CLI training, killed and resumed): about 8 minutes on 2 cores
def test_killed_run_resumes_from_its_last_checkpoint(resumed, built):
    out, killed_at = resumed
    assert killed_at >= 64
    progress = json.loads((out / "progress.json").read_text())
    assert progress["resumes"] == 1 and killed_at < progress["global_step"] < 2 * (killed_at + 64)
    assert (out / "tensorboard").is_dir() and len(list((out / "tensorboard").iterdir())) >= 2
    # Resuming with other options (here another seed) is refused.
    other = subprocess.run(_train(out, built["ball"][0], killed_at + 64, "--resume", "--seed", "3"),
                           capture_output=True, text=True)
    assert other.returncode == 2 and "other settings" in other.stdout + other.stderr


@pytest.mark.slow  # the resumed run (a real CLI training, killed and resumed): about 8 minutes on 2 cores
def test_saved_policy_loads_for_inference(resumed):
    out, _ = resumed
    policy, env_config, ppo = load_policy(out / "policy")
    assert env_config.feet == "ball" and env_config.policy == "B" and ppo.num_envs == 8
    action, _ = policy(jp.zeros(48), jax.random.PRNGKey(0))
    assert action.shape == (12,) and bool(jp.isfinite(action).all())
    with pytest.raises(InputError, match="not a footforge policy"):
        load_policy(out / "checkpoints")


@pytest.mark.slow  # the resumed run (a real CLI training, killed and resumed): about 8 minutes on 2 cores
def test_evaluation_produces_every_index_also_zero_shot(resumed, built, tmp_path):
    from footforge.evaluate import INDICES
    out, _ = resumed
    report = tmp_path / "eval"
    code = subprocess.run([sys.executable, str(REPO / "pipelines/evaluate.py"), "--policy", str(out / "policy"),
                           "--feet", "aff", "--num-envs", "2", "--seconds", "0.4", "--build-root",
                           str(built["aff"][0].parent), "--out", str(report)], capture_output=True, text=True)
    assert code.returncode == 0, code.stderr[-2000:]
    metrics = json.loads((report / "metrics.json").read_text())
    assert metrics[0]["feet"] == "aff" and metrics[0]["trained_on"] == "ball"  # the zero-shot case
    for name in INDICES:
        assert np.isfinite(metrics[0]["indices"][name]["mean"]), name
    assert np.isfinite(metrics[0]["slippage"]) or metrics[0]["falls"] == 2
    for name in ("comparison.md", "comparison.png", "contacts_0.png", "push_response_0.png", "policy_card.md"):
        assert (report / name).is_file()
    card = (report / "policy_card.md").read_text()  # the run's training, this evaluation's indices
    assert "on aff feet (zero-shot)" in card and "| machine | 1 x " in card and "over 2 calls" in card
    for name in INDICES:
        index = metrics[0]["indices"][name]
        assert f"{index['mean']:.4g} ± {index['std']:.4g}" in card, name


@pytest.mark.slow
def test_privileged_critic_trains_and_its_policy_loads(built, tmp_path):
    """Brax PPO with the asymmetric critic: a tiny run, then the saved policy acts on the
    environment's dict observations and on the policy's slice alone."""
    from dataclasses import replace

    from footforge import train

    cfg = replace(envs.default_config("flat", "ball", "B"), build_dir=str(built["ball"][0]), episode_length_s=1.0,
                  privileged_critic=True)
    ppo = PPOConfig(num_envs=8, unroll_length=4, batch_size=8, num_minibatches=1, num_timesteps=64,
                    checkpoint_every_steps=32, num_eval_envs=4, policy_hidden_layers=(16,), value_hidden_layers=(16,))
    train.train(cfg, ppo, tmp_path / "run")
    policy, env_config, _ = load_policy(tmp_path / "run" / "policy")
    assert env_config.privileged_critic
    env = envs.from_config(env_config)
    state = env.reset(jax.random.PRNGKey(0))
    action, _ = policy(state.obs, jax.random.PRNGKey(1))
    assert action.shape == (12,) and bool(jp.isfinite(action).all())


def test_initial_policy_of_a_privileged_critic_loads_and_acts(tmp_path):
    """initial_policy builds the asymmetric networks a privileged config names; load_policy reads
    them back, and the policy acts on the dict observation and its `state` slice only."""
    from dataclasses import replace

    from footforge import train

    cfg = replace(envs.default_config("flat", "ball", "B"), privileged_critic=True)
    ppo = PPOConfig(policy_hidden_layers=(8,), value_hidden_layers=(8,))
    sizes = {"state": (48,), "privileged_state": (48 + 148,)}
    train.initial_policy(cfg, ppo, tmp_path / "policy", observation_size=sizes)
    policy, env_config, _ = load_policy(tmp_path / "policy")
    assert env_config.privileged_critic
    obs = {"state": jp.ones(48), "privileged_state": jp.zeros(48 + 148)}
    action, _ = policy(obs, jax.random.PRNGKey(0))
    other, _ = policy({"state": jp.ones(48), "privileged_state": jp.ones(48 + 148)}, jax.random.PRNGKey(0))
    assert action.shape == (12,)
    np.testing.assert_array_equal(action, other)  # the critic's slice does not reach the policy


@pytest.mark.slow  # a real training stopped by its budget: about 3 minutes on 2 cores
def test_time_budget_stops_at_a_checkpoint(built, tmp_path):
    """--max-minutes: a run whose first epoch (compilation included) outlasts the budget stops
    after that epoch's checkpoint and evaluation, with its policy written and the stop recorded."""
    out = tmp_path / "run"
    done = subprocess.run(_train(out, built["ball"][0], 100_000, "--max-minutes", "0.05"),
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "wall-time budget" in done.stdout
    progress = json.loads((out / "progress.json").read_text())
    assert progress["stopped"] == "wall-time budget" and progress["global_step"] == 32
    assert json.loads((out / "policy/footforge.json").read_text())["global_step"] == 32
    assert latest_checkpoint(out)[0] == 32
