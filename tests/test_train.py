"""Flat-task training: hyperparameter checks, config round trip, a run killed with SIGKILL and
resumed from its last checkpoint, and the saved policy loaded for inference."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jp
import numpy as np
import pytest

from footforge import envs
from footforge.envs import observation_layout, rewards
from footforge.envs.config import EnvConfig
from footforge.errors import InputError
from footforge.rl.train import (
    PPOConfig,
    env_config_from_dict,
    from_dict,
    latest_checkpoint,
    load_policy,
    to_dict,
)

from conftest import REPO

TINY = [
    "--num-envs",
    "8",
    "--unroll-length",
    "4",
    "--batch-size",
    "8",
    "--minibatches",
    "1",
    "--eval-envs",
    "4",
    "--checkpoint-every",
    "32",
]


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
    # What is declared in code (the observation groups' reading functions) is not saved, and
    # loading restores it from the declaration.
    saved = json.loads(json.dumps(to_dict(env)))
    assert saved["observations"]["joint_vel"] == {"scale": 0.05, "noise": 1.5}
    assert saved["rewards"]["lin_vel_z"] == {"scale": -0.03, "params": {}}
    assert saved["rewards"]["lin_vel_xy"] == {"scale": 2.0, "params": {"sigma": 0.25}}
    with pytest.raises(InputError, match="unknown configuration key 'lin_vel_scael'"):
        env_config_from_dict({**saved, "observations": {"lin_vel_scael": 2.0}})


def test_configs_saved_before_terms_were_declared_once_load_unchanged():
    """config.json of runs from before 2026-11-26 (flat scale and noise keys, bare reward scales),
    such as the GPU campaign's, load with every value in its new place."""
    old = json.loads(
        (Path(__file__).parents[1] / "benchmarks" / "gpu_campaign_2026-11-24" / "flat_aof_B.config.json").read_text()
    )["env"]
    env = env_config_from_dict(old)
    o, r = env.observations, env.rewards
    assert (o.base_lin_vel.scale, o.base_lin_vel.noise) == (
        old["observations"]["lin_vel_scale"],
        old["observations"]["lin_vel_noise"],
    )
    assert o.command.scale == tuple(old["observations"]["command_scale"])
    assert (o.height_scan.scale, o.height_scan.noise) == (
        old["observations"]["height_scale"],
        old["observations"]["height_noise_m"],
    )
    assert o.foot_joint_vel.noise == old["observations"]["foot_joint_vel_noise"]
    # Terms added since (feet_air_time) load switched off, as those runs trained.
    assert "feet_air_time" not in old["rewards"] and r.feet_air_time.scale == 0.0
    assert {name: term.scale for name, term in rewards.terms(r).items()} == {
        name: old["rewards"].get(name, 0.0) for name in rewards.terms(r)
    }
    assert r.fall == old["rewards"]["fall"]
    # One tracking_sigma then, each tracking term's own sigma now; the base height's target its own too.
    assert r.lin_vel_xy.params == r.yaw_rate.params == {"sigma": old["rewards"]["tracking_sigma"]}
    assert r.base_height.params == {"target_m": old["rewards"]["base_height_target_m"]}


def test_a_tiny_ppo_run_trains_end_to_end(built, tmp_path):
    """Brax PPO on the flat environment stepped by MuJoCo's C engine (the CPU's default), two
    epochs of 8 robots x 4 steps: an evaluation at the start and at each checkpoint, finite, the
    policy's parameters updated between the checkpoints, and a final policy that loads and acts.
    Whether PPO learns is a benchmark (benchmarks/learning_stand_up.py: 98 k steps that teach
    the robot to hold itself up; benchmarks/learning_cpu.py: walking)."""
    from dataclasses import replace

    from footforge.rl import train
    from footforge.rl.checkpoints import checkpoints, load_parameters

    cfg = replace(
        envs.default_config("flat", "ball", "B"),
        build_dir=str(built["ball"][0]),
        episode_length_s=1.0,
        physics="mujoco",
    )
    ppo = PPOConfig(**SMALL_PPO | {"num_timesteps": 64})
    train.train(cfg, ppo, tmp_path / "run", notice=lambda text: None)
    logged = [json.loads(line) for line in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()]
    evaluations = [(m["global_step"], m["eval/episode_reward"]) for m in logged if "eval/episode_reward" in m]
    assert [step for step, _ in evaluations] == [0, 32, 64], evaluations
    assert all(np.isfinite(value) for _, value in evaluations), evaluations
    (first_step, first), (last_step, last) = checkpoints(tmp_path / "run")
    assert (first_step, last_step) == (32, 64)
    kernels = [_kernel(load_parameters(folder)) for folder in (first, last)]
    assert np.isfinite(kernels[1]).all() and not np.array_equal(*kernels)
    policy, env_config, saved_ppo = load_policy(tmp_path / "run" / "policy")
    assert (env_config, saved_ppo) == (cfg, ppo)
    action, _ = policy(jp.zeros(observation_layout.size(env_config, 0)), jax.random.PRNGKey(0))
    assert action.shape == (12,) and bool(jp.isfinite(action).all())


def _train(out, build_dir, timesteps, *extra):
    return [
        sys.executable,
        str(REPO / "pipelines/train_flat.py"),
        "--feet",
        "ball",
        "--build-root",
        str(build_dir.parent),
        "--timesteps",
        str(timesteps),
        "--out",
        str(out),
        *TINY,
        *extra,
    ]


@pytest.fixture(scope="module")
def resumed(built, tmp_path_factory):
    """A tiny run killed with SIGKILL after its second checkpoint, then resumed: (run dir, step at the
    kill, the resumed run's stdout)."""
    out = tmp_path_factory.mktemp("train") / "run"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        _train(out, built["ball"][0], 100_000),
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    # Each evaluation prints a progress line after its checkpoint is written: the lines are the
    # events to look at the checkpoints on (no polling; the test's timeout bounds the wait).
    for _ in proc.stdout:
        if (latest_checkpoint(out) or (0,))[0] >= 64:
            break
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    proc.stdout.close()
    reached = latest_checkpoint(out)
    assert reached is not None and reached[0] >= 64, f"training ended before its second checkpoint (reached: {reached})"
    killed_at, _ = reached
    assert not (out / "policy").exists()
    # Resume with the same options and a total just past the checkpoint: it must continue, not
    # restart. 50 more steps are not whole iterations of 32: Brax runs 64, as the run announces.
    done = subprocess.run(
        _train(out, built["ball"][0], killed_at + 50, "--resume", "--shorten"),
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return out, killed_at, done.stdout


@pytest.mark.slow  # the resumed run (a real CLI training, killed and resumed): about 8 minutes on 2 cores
@pytest.mark.timeout(1500)  # explicit budget: several times its time on 2 quiet cores
def test_killed_run_resumes_from_its_last_checkpoint(resumed, built):
    from footforge.rl import train

    out, killed_at, stdout = resumed
    assert killed_at >= 64
    progress = json.loads((out / "progress.json").read_text())
    _, ppo = train.load_run_config(out)
    assert ppo.num_timesteps == killed_at + 50
    assert progress["resumes"] == 1 and progress["global_step"] == train.planned_steps(ppo, killed_at) == killed_at + 64
    assert f"steps {killed_at:,} -> {killed_at + 64:,} (--timesteps {killed_at + 50:,} rounded up" in stdout
    assert (out / "tensorboard").is_dir() and len(list((out / "tensorboard").iterdir())) >= 2
    # One curve over the kill: steps and cumulative wall time never go back, no step evaluated twice.
    curve = _curve_rows(out)
    steps, evaluations = (
        [r["global_step"] for r in curve],
        [r["global_step"] for r in curve if "eval/episode_reward" in r],
    )
    assert steps == sorted(steps) and [r["wall_s"] for r in curve] == sorted(r["wall_s"] for r in curve), curve
    assert len(evaluations) == len(set(evaluations)) and evaluations[-1] == killed_at + 64, evaluations
    # Resuming with other options (here another seed) is refused, naming the option.
    other = subprocess.run(
        _train(out, built["ball"][0], killed_at + 64, "--resume", "--seed", "3", "--shorten"),
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert other.returncode == 2 and "--seed 3 differs from the run's 0" in other.stderr


@pytest.mark.slow  # the resumed run (a real CLI training, killed and resumed): about 8 minutes on 2 cores
@pytest.mark.timeout(1500)  # explicit budget: several times its time on 2 quiet cores
def test_saved_policy_loads_for_inference(resumed):
    out, _, _ = resumed
    policy, env_config, ppo = load_policy(out / "policy")
    assert env_config.feet == "ball" and env_config.policy == "B" and ppo.num_envs == 8
    action, _ = policy(jp.zeros(observation_layout.size(env_config, 0)), jax.random.PRNGKey(0))
    assert action.shape == (12,) and bool(jp.isfinite(action).all())
    with pytest.raises(InputError, match="not a footforge policy"):
        load_policy(out / "checkpoints")


@pytest.mark.slow  # the resumed run (a real CLI training, killed and resumed): about 8 minutes on 2 cores
@pytest.mark.timeout(1500)  # explicit budget: several times its time on 2 quiet cores
def test_evaluation_produces_every_index_also_zero_shot(resumed, built, tmp_path):
    from footforge.rl.evaluate import INDICES

    out, _, _ = resumed
    report = tmp_path / "eval"
    code = subprocess.run(
        [
            sys.executable,
            str(REPO / "pipelines/evaluate.py"),
            "--policy",
            str(out / "policy"),
            "--feet",
            "aff",
            "--num-envs",
            "2",
            "--seconds",
            "0.4",
            "--build-root",
            str(built["aff"][0].parent),
            "--out",
            str(report),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
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
@pytest.mark.timeout(900)  # explicit budget: several times its time on 2 quiet cores
def test_privileged_critic_trains_and_its_policy_loads(built, tmp_path):
    """Brax PPO with the asymmetric critic: a tiny run, then the saved policy acts on the
    environment's dict observations and on the policy's slice alone."""
    from dataclasses import replace

    from footforge.rl import train

    # The C engine (the CPU's default): under MJX this test spent 4.8 minutes compiling.
    cfg = replace(
        envs.default_config("flat", "ball", "B"),
        build_dir=str(built["ball"][0]),
        episode_length_s=1.0,
        privileged_critic=True,
        physics="mujoco",
    )
    ppo = PPOConfig(
        num_envs=8,
        unroll_length=4,
        batch_size=8,
        num_minibatches=1,
        num_timesteps=64,
        checkpoint_every_steps=32,
        num_eval_envs=4,
        policy_hidden_layers=(16,),
        value_hidden_layers=(16,),
    )
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

    from footforge.rl import train

    cfg = replace(envs.default_config("flat", "ball", "B"), privileged_critic=True)
    ppo = PPOConfig(policy_hidden_layers=(8,), value_hidden_layers=(8,))
    n = observation_layout.size(cfg, 0)
    sizes = {"state": (n,), "privileged_state": (n + 148,)}
    train.initial_policy(cfg, ppo, tmp_path / "policy", observation_size=sizes)
    policy, env_config, _ = load_policy(tmp_path / "policy")
    assert env_config.privileged_critic
    obs = {"state": jp.ones(n), "privileged_state": jp.zeros(n + 148)}
    action, _ = policy(obs, jax.random.PRNGKey(0))
    other, _ = policy({"state": jp.ones(n), "privileged_state": jp.ones(n + 148)}, jax.random.PRNGKey(0))
    assert action.shape == (12,)
    np.testing.assert_array_equal(action, other)  # the critic's slice does not reach the policy


@pytest.mark.slow  # a real training stopped by its budget: about 3 minutes on 2 cores
@pytest.mark.timeout(900)  # explicit budget: several times its time on 2 quiet cores
@pytest.mark.parametrize("evaluations", [True, pytest.param(False, marks=pytest.mark.slow)])
def test_time_budget_stops_at_a_checkpoint(built, tmp_path, evaluations):
    """--max-minutes: a run whose first epoch (compilation included) outlasts the budget stops
    after that epoch's checkpoint (and evaluation, unless --no-evaluations), with its policy
    written and the stop recorded."""
    out = tmp_path / "run"
    done = subprocess.run(
        _train(out, built["ball"][0], 100_000, "--max-minutes", "0.05", *([] if evaluations else ["--no-evaluations"])),
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "wall-time budget" in done.stdout
    assert "step 32/100,000" in done.stdout  # the plain progress line of a log (stdout is no terminal)
    progress = json.loads((out / "progress.json").read_text())
    assert progress["stopped"] == "wall-time budget" and progress["global_step"] == 32
    assert json.loads((out / "policy/footforge.json").read_text())["global_step"] == 32
    assert latest_checkpoint(out)[0] == 32
    logged = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert any("eval/episode_reward" in m for m in logged) == evaluations


# --- run folders, checkpoints that fail verification, the command line's messages ---


def _params(seed: int, ppo: PPOConfig):
    """(normaliser, policy, value) parameters of a 48-input network, as Brax's PPO passes them."""
    from brax.training.acme import running_statistics, specs

    from footforge.rl import train

    nets = train.network_factory(ppo)(
        observation_size=48, action_size=12, preprocess_observations_fn=running_statistics.normalize
    )
    k_policy, k_value = jax.random.split(jax.random.PRNGKey(seed))
    return (
        running_statistics.init_state(specs.Array((48,), jp.dtype("float32"))),
        nets.policy_network.init(k_policy),
        nets.value_network.init(k_value),
    )


def _kernel(params):
    return np.asarray(params[1]["params"]["MLP_0"]["hidden_0"]["kernel"])


SMALL_PPO = dict(
    num_envs=8,
    unroll_length=4,
    batch_size=8,
    num_minibatches=1,
    num_eval_envs=4,
    checkpoint_every_steps=32,
    num_timesteps=96,
    policy_hidden_layers=(8,),
    value_hidden_layers=(8,),
)


@pytest.fixture
def written_run(built, tmp_path):
    """A run folder as train() leaves it after two epochs (steps 32 and 64), its checkpoints
    written by train.save_checkpoint (what train's Brax callback calls) from parameters of seeds
    32 and 64: (run folder, env config, PPO config)."""
    from dataclasses import replace

    from footforge.rl import train

    cfg = replace(envs.default_config("flat", "ball", "B"), build_dir=str(built["ball"][0]))
    ppo = PPOConfig(**SMALL_PPO)
    run = train.prepare_run_dir(tmp_path / "run")
    (run / "config.json").write_text(json.dumps({"env": to_dict(cfg), "ppo": to_dict(ppo)}))
    (run / "metrics.jsonl").write_text('{"global_step": 0}\n')
    (run / "tensorboard").mkdir()
    (run / "tensorboard" / "events.out.tfevents.1").write_bytes(b"x")
    for step in (32, 64):
        train.save_checkpoint(run, step, _params(step, ppo), 48, 12, ppo)
    (run / "progress.json").write_text(json.dumps({"global_step": 64, "resumes": 0, "metrics": {}}))
    return run, cfg, ppo


def _truncate_data(checkpoint):
    """Cuts the largest of orbax's data files in half (a write cut short, a full disk)."""
    data = max((p for p in checkpoint.rglob("*") if p.is_file() and "/d/" in str(p)), key=lambda p: p.stat().st_size)
    data.write_bytes(data.read_bytes()[: data.stat().st_size // 2])


def _fake_ppo(calls):
    """Stands in for Brax's PPO in train(): records what it was given and runs one epoch's
    callbacks (a checkpoint and an evaluation) with the restored parameters."""

    def run(ppo_train, env, env_config, ppo, remaining, epochs, restore, resumes, log, save, *rest):
        calls.append({"remaining": remaining, "restore": restore, "resumes": resumes})
        save(remaining, None, restore)
        log(remaining, {"eval/episode_reward": 1.0, "eval/walltime": 0.1})

    return run


def test_checkpoints_carry_a_manifest_that_catches_damage(written_run):
    from footforge.rl import train

    run, _, _ = written_run
    (_, good), (_, newest) = train.checkpoints(run)
    assert (newest / train.CHECKPOINT_MANIFEST).is_file()
    assert train.checkpoint_problem(good) is None and train.checkpoint_problem(newest) is None
    _truncate_data(newest)
    assert "bytes" in train.checkpoint_problem(newest, read=False)
    assert train.latest_intact_checkpoint(run) == (32, good)
    (good / "_METADATA").write_text("")
    assert "_METADATA has 0 bytes" in train.checkpoint_problem(good, read=False)
    assert train.latest_intact_checkpoint(run) is None
    assert train.latest_checkpoint(run) == (64, newest)  # the newest, intact or not


@pytest.mark.parametrize("damage", ["truncated data", "empty _METADATA"])
def test_resume_skips_a_damaged_checkpoint_and_says_so(written_run, monkeypatch, capsys, damage):
    from footforge.rl import train

    run, cfg, ppo = written_run
    newest = train.latest_checkpoint(run)[1]
    if damage == "truncated data":
        _truncate_data(newest)
    else:
        (newest / "_METADATA").write_text("")
    calls = []
    monkeypatch.setattr(train, "_run_ppo", _fake_ppo(calls))
    train.train(cfg, ppo, run, resume=True)
    err = capsys.readouterr().err
    assert f"skipping checkpoint {newest.name}" in err and str(run) in err
    # Resumed from step 32 (the intact one): 64 steps remain, with checkpoint 32's parameters.
    assert calls[0]["remaining"] == 96 - 32 and calls[0]["resumes"] == 1
    np.testing.assert_array_equal(_kernel(calls[0]["restore"]), _kernel(_params(32, ppo)))
    assert (run / "checkpoints" / f"{newest.name}.corrupt").is_dir()  # kept aside, not deleted
    assert [s for s, _ in train.checkpoints(run)] == [32, 96]
    assert json.loads((run / "policy" / "footforge.json").read_text())["global_step"] == 96
    assert train.checkpoint_problem(run / "policy", read=False) is None


def test_a_shipped_run_without_checkpoints_resumes_from_its_policy(written_run, monkeypatch, capsys):
    """A shipped policy's folder keeps its weights once: policy/ (the newest checkpoint's files and
    footforge.json), no checkpoints/. --resume then continues from policy/, with its parameters and
    step, and the extended run writes its checkpoints and a new policy/ as any run does; a damaged
    policy/ is refused as a damaged checkpoint is."""
    import shutil

    from footforge.rl import train

    run, cfg, ppo = written_run
    train.write_policy(run, cfg, ppo, {})
    shutil.rmtree(run / "checkpoints")
    assert train.latest_intact_checkpoint(run) == (64, run / "policy") and train.policy_problem(run) is None
    calls = []
    monkeypatch.setattr(train, "_run_ppo", _fake_ppo(calls))
    train.train(cfg, ppo, run, resume=True)
    assert calls[0]["remaining"] == 96 - 64 and calls[0]["resumes"] == 1
    np.testing.assert_array_equal(_kernel(calls[0]["restore"]), _kernel(_params(64, ppo)))
    assert [s for s, _ in train.checkpoints(run)] == [96]
    assert json.loads((run / "policy" / "footforge.json").read_text())["global_step"] == 96
    shutil.rmtree(run / "checkpoints")
    _truncate_data(run / "policy")
    with pytest.raises(train.InputError, match="no intact checkpoint to resume"):
        train.train(cfg, ppo, run, resume=True)
    assert "skipping checkpoint policy" in capsys.readouterr().err and (run / "policy").is_dir()


def test_resume_with_every_checkpoint_damaged_is_an_input_error(written_run, capsys):
    from footforge.cli.train import main
    from footforge.rl import train

    run, _, _ = written_run
    for _, folder in train.checkpoints(run):
        _truncate_data(folder)
    assert main("flat", "", ["--out", str(run), "--resume"]) == 2
    out = capsys.readouterr()
    assert "no intact checkpoint to resume in" in out.err and str(run) in out.err and "--force" in out.err
    assert out.err.count("skipping checkpoint") == 2 and "error" not in out.out
    assert not list((run / "checkpoints").glob("*.corrupt"))  # nothing renamed when nothing resumes


def test_an_existing_run_is_refused_without_resume_or_force(written_run, capsys):
    from footforge.cli.train import main

    run, _, _ = written_run
    before = {p: p.read_bytes() for p in run.rglob("*") if p.is_file()}
    assert main("flat", "", ["--feet", "ball", "--out", str(run), *TINY]) == 2
    out = capsys.readouterr()
    assert "holds a training run (its last checkpoint at step 64)" in out.err and "--resume" in out.err
    assert out.out == ""
    assert {p: p.read_bytes() for p in run.rglob("*") if p.is_file()} == before  # untouched
    assert main("flat", "", ["--out", str(run), "--resume", "--force"]) == 2
    assert "exclude each other" in capsys.readouterr().err


@pytest.mark.parametrize("task", ["flat", "rough"])
def test_several_processes_are_refused_before_any_work(task, tmp_path, capsys):
    """--coordinator: Brax 0.14.2's PPO does not train over several JAX processes on JAX 0.9
    (footforge.cli.train.MULTI_PROCESS_UNSUPPORTED says how it fails); the command says so at once,
    exit 2, and writes nothing (JAX's distributed service is never started)."""
    import jax

    from footforge.cli.train import main

    out = tmp_path / "run"
    assert (
        main(
            task,
            "",
            [
                "--feet",
                "ball",
                "--out",
                str(out),
                "--coordinator",
                "127.0.0.1:1",
                "--num-processes",
                "2",
                "--process-id",
                "0",
                *TINY,
            ],
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "--coordinator" in err and "Brax 0.14.2" in err and "one machine" in err
    assert not out.exists() and jax.process_count() == 1


@pytest.mark.parametrize(
    "flags, flag",
    [(["--timesteps", "-5"], "--timesteps"), (["--num-envs", "0"], "--num-envs"), (["--num-envs", "96"], "--num-envs")],
)
def test_bad_ppo_settings_are_refused_in_the_flags_words_before_anything_is_announced(flags, flag, tmp_path, capsys):
    """A PPO setting Brax would reject exits 2 naming the flag (not PPOConfig's field), before the
    run is announced, any build is made or any folder written."""
    from footforge.cli.train import main

    out = tmp_path / "run"
    assert main("flat", "", ["--feet", "ball", "--out", str(out), *TINY, *flags]) == 2
    captured = capsys.readouterr()
    assert flag in captured.err and "num_envs" not in captured.err and "num_timesteps" not in captured.err
    assert "steps 0" not in captured.out + captured.err and not out.exists()


def test_init_from_hands_the_source_s_newest_parameters_to_brax(written_run, tmp_path, monkeypatch):
    """A new run initialised from another: Brax's PPO receives the source's newest checkpoint (step
    64, parameters of seed 64) as restore_params, under the new run's own settings; the run records
    its source. Networks that do not fit, or --resume beside it, are refused before any folder is
    written. (Brax's restoring itself is what --resume's tests train through.)"""
    from dataclasses import replace

    from brax.training.agents.ppo import train as ppo_train

    from footforge.rl import train

    run, cfg, ppo = written_run
    seen = {}
    monkeypatch.setattr(ppo_train, "train", lambda **kwargs: seen.update(kwargs))
    tuned = replace(ppo, entropy_cost=0.001, learning_rate=1e-4)
    monkeypatch.chdir(run.parent)  # a relative source, as a user types it (orbax wants absolute paths)
    train.train(cfg, tuned, tmp_path / "tuned", init_from=Path(run.name), notice=lambda text: None)
    restored, expected = jax.tree_util.tree_leaves(seen["restore_params"]), jax.tree_util.tree_leaves(_params(64, ppo))
    assert len(restored) == len(expected) > 0
    for a, b in zip(restored, expected):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert seen["entropy_cost"] == 0.001 and seen["learning_rate"] == 1e-4
    config = json.loads((tmp_path / "tuned" / "config.json").read_text())
    assert config["initialised_from"] == {"run": str(run), "step": 64, "steps_before": 64}
    # A source that was itself initialised from another run passes its own steps on: the lineage's count.
    saved = json.loads((run / "config.json").read_text())
    (run / "config.json").write_text(json.dumps(saved | {"initialised_from": {"run": "/r", "step": 1000}}))
    train.train(cfg, tuned, tmp_path / "tuned_again", init_from=run, notice=lambda text: None)
    again = json.loads((tmp_path / "tuned_again" / "config.json").read_text())["initialised_from"]
    assert again == {"run": str(run), "step": 64, "steps_before": 1064}
    assert train.steps_before(again) == 1064 and train.steps_before({"run": "/r", "step": 1000}) == 1000
    assert config["ppo"]["entropy_cost"] == 0.001
    with pytest.raises(InputError, match=r"policy_hidden_layers \(8,\) there, \(16,\) here"):
        train.train(cfg, replace(ppo, policy_hidden_layers=(16,)), tmp_path / "other", init_from=run)
    with pytest.raises(InputError, match="observation width 48 there, 60 here"):
        train.train(
            replace(cfg, observations=replace(cfg.observations, pd_targets=True)),
            ppo,
            tmp_path / "other",
            init_from=run,
        )
    with pytest.raises(InputError, match="--resume continues"):
        train.train(cfg, ppo, tmp_path / "other", init_from=run, resume=True)
    assert not (tmp_path / "other").exists()


def test_force_removes_only_what_footforge_wrote(written_run):
    from footforge.outputs import MARKER
    from footforge.rl import train

    run, _, _ = written_run
    (run / "notes.txt").write_text("mine")
    (run / ".policy.tmp-1-abc").mkdir()  # a killed run's temporary
    (run / ".notes.tmp").write_text("mine too")
    messages = []
    train.prepare_run_dir(run, force=True, notice=messages.append)
    assert sorted(p.name for p in run.iterdir()) == [MARKER, ".notes.tmp", "notes.txt"]
    assert "checkpoints" in messages[0] and "notes.txt" not in messages[0]


def test_a_folder_of_the_user_is_refused_and_never_emptied(tmp_path):
    from footforge.rl import train

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "config.json").write_text('{"mine": true}')
    with pytest.raises(InputError, match="footforge did not write"):
        train.prepare_run_dir(mine)
    with pytest.raises(InputError, match="holds config.json, which footforge did not write"):
        train.prepare_run_dir(mine, force=True)
    assert (mine / "config.json").read_text() == '{"mine": true}'
    (mine / "config.json").unlink()
    (mine / "thesis.tex").write_text("x")
    train.prepare_run_dir(mine, force=True)  # beside the user's files, which stay
    assert (mine / "thesis.tex").read_text() == "x" and train.is_run_folder(mine)


def test_an_evaluation_does_not_replace_a_run_folder(written_run):
    from footforge.outputs import check_output_folder

    run, _, _ = written_run
    with pytest.raises(InputError, match="is a training run folder"):
        check_output_folder(run)


def _capture_train(monkeypatch):
    from footforge.rl import train

    seen = {}

    def fake(env_config, ppo, run_dir, **kwargs):
        seen.update(env=env_config, ppo=ppo, kwargs=kwargs)
        return {"eval/episode_reward": 0.0}

    monkeypatch.setattr(train, "train", fake)
    return seen


def test_resume_reads_the_run_s_settings_and_names_a_differing_flag(written_run, monkeypatch, capsys):
    from footforge.cli.train import main

    run, cfg, ppo = written_run
    seen = _capture_train(monkeypatch)
    assert main("flat", "", ["--out", str(run), "--resume", "--timesteps", "160"]) == 0
    # The engine is this machine's (--physics auto), whatever the run last used: the rest is the run's.
    from dataclasses import replace

    from footforge.envs import engine

    assert seen["env"] == replace(cfg, physics=engine.resolve("auto"))
    assert seen["ppo"] == replace_ppo(ppo, num_timesteps=160)
    assert seen["kwargs"]["resume"] is True
    capsys.readouterr()
    assert main("flat", "", ["--out", str(run), "--resume", "--num-envs", "8", "--seed", "3"]) == 2
    err = capsys.readouterr().err
    assert "--seed 3 differs from the run's 0" in err and "--num-envs" not in err
    assert main("flat", "", ["--out", str(run), "--resume", "--build-root", str(run)]) == 2
    assert "--build-root" in capsys.readouterr().err
    assert main("rough", "", ["--out", str(run), "--resume"]) == 2
    assert "footforge train flat" in capsys.readouterr().err


def replace_ppo(ppo, **changes):
    from dataclasses import replace

    return replace(ppo, **changes)


def test_build_root_names_the_builds_everywhere_and_build_dir_still_works(built, monkeypatch, capsys, tmp_path):
    from footforge.cli.train import main

    seen = _capture_train(monkeypatch)
    root = built["ball"][0].parent
    assert main("flat", "", ["--feet", "ball", "--build-root", str(root), "--out", str(tmp_path / "a")]) == 0
    assert seen["env"].build_dir == str(root / "ball")
    assert main("flat", "", ["--feet", "ball", "--build-dir", str(root / "ball"), "--out", str(tmp_path / "b")]) == 0
    assert seen["env"].build_dir == str(root / "ball")
    assert "--build-dir is deprecated; use --build-root" in capsys.readouterr().err
    assert main("flat", "", ["--help"]) == 0  # an exit code, as from every command's main
    help_text = capsys.readouterr().out
    assert "--build-root" in help_text
    assert "--build-dir" not in help_text  # hidden


def test_a_missing_policy_folder_is_said_not_to_exist(tmp_path, capsys):
    import importlib.util

    missing = tmp_path / "runs" / "flat_aof_B" / "policy"
    with pytest.raises(InputError, match="does not exist"):
        load_policy(missing)
    spec = importlib.util.spec_from_file_location("pipeline_evaluate", REPO / "pipelines" / "evaluate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    from mujoco import mjx  # noqa: F401  (its first import prints about the optional warp backend)

    capsys.readouterr()
    assert module.main(["--policy", str(missing), "--out", str(tmp_path / "eval")]) == 2
    out = capsys.readouterr()
    assert f"{missing} does not exist" in out.err and "footforge.json" not in out.err and out.out == ""


def test_progress_is_printed_as_plain_lines_when_not_a_terminal():
    import io

    from rich.console import Console

    from footforge.cli.train import _Reporter

    log = io.StringIO()
    metrics = {"eval/episode_reward": 12.5, "eval/episode_error/lin_vel_x_per_step": 0.25}
    with _Reporter(Console(file=log), "flat", 1000) as report:  # a file: not a terminal
        report(0, 1000, metrics, True)
        report(250, 1000, metrics, False)  # a training-episodes log: no line
        report(500, 1000, metrics | {"eval/episode_diverged": 0.25}, True)
    lines = log.getvalue().splitlines()
    assert len(lines) == 3 and lines[0].startswith("compiling and training")
    assert lines[1].startswith("step 0/1,000 (0%)  return   12.50  vx error 0.250 m/s")
    assert lines[2].startswith("step 500/1,000 (50%)") and "diverged 0.25" in lines[2]
    terminal = io.StringIO()
    with _Reporter(Console(file=terminal, force_terminal=True), "flat", 1000) as report:
        report(500, 1000, metrics, True)
    assert "step 500/1,000" not in terminal.getvalue()  # the bar instead


def test_training_errors_go_to_stderr(written_run):
    """The pipeline as a batch job runs it: the error on stderr, exit 2, nothing on stdout."""
    run, _, _ = written_run
    done = subprocess.run(
        [sys.executable, str(REPO / "pipelines/train_flat.py"), "--feet", "ball", "--out", str(run)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 2 and done.stdout == ""
    assert "footforge train flat: error:" in done.stderr and "holds a training run" in done.stderr


def test_a_terminated_training_run_ends_as_an_interrupted_one(tmp_path, monkeypatch, capsys):
    """SIGTERM (a batch scheduler's kill) during training: no traceback, exit 143 (128 + 15, as a
    shell reports a terminated process), and stderr says what the run folder keeps and how to
    continue."""
    from footforge.cli import train as train_cli
    from footforge.rl import train as train_lib

    def terminated(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler interrupts this
        raise AssertionError("SIGTERM did not interrupt training")

    monkeypatch.setattr(train_lib, "train", terminated)
    before = signal.getsignal(signal.SIGTERM)
    code = train_cli.main("flat", "test", ["--feet", "ball", "--out", str(tmp_path / "run")])
    captured = capsys.readouterr()
    assert code == 143
    assert "footforge train flat: terminated; no checkpoint was written" in captured.err
    assert signal.getsignal(signal.SIGTERM) is before  # the handler is the pipeline's only while it trains


def test_the_first_epoch_is_estimated_from_the_throughput_not_its_compilation():
    """--max-minutes: after the first epoch (compilation included) the next is estimated from the
    measured steps/s plus an evaluation; later epochs by the last one's time. The H100 campaign's
    AFF job stopped at 4.8 of 8.5 minutes when its 4.8-minute first epoch was the estimate."""
    from footforge.rl.train import next_epoch_seconds

    # 4 M steps at 46,000 steps/s: 87 s, plus a 75 s evaluation; the first epoch took 290 s.
    assert next_epoch_seconds(290.0, True, 46_000.0, 4_000_000, 75.0) == pytest.approx(4e6 / 46e3 + 75.0)
    assert next_epoch_seconds(290.0, True, None, 4_000_000) == 290.0  # no throughput measured
    assert next_epoch_seconds(90.0, False, 46_000.0, 4_000_000) == 90.0  # a later epoch: its own time
    assert next_epoch_seconds(10.0, True, 1_000.0, 4_000_000) == 10.0  # never above what was observed


def test_contact_model_flag_sets_the_model_s_physics_and_resume_keeps_it(written_run, monkeypatch, capsys, tmp_path):
    """Training uses contact_model 'stance' by default, with the step and solver iterations it
    needs on the chosen feet; --contact-model fast sets fast's own physics (ball feet back at
    5 ms x 4, 4/8 iterations; envs.physics); a resumed run names a differing --contact-model."""
    from footforge import envs as envs_module
    from footforge.cli.train import main

    seen = _capture_train(monkeypatch)
    switched = []  # x64 is process-wide: recorded here, not switched in the test process
    monkeypatch.setattr(envs_module, "enable_float64_physics", lambda config: switched.append(config.float64_physics))
    assert main("flat", "", ["--feet", "aof", "--out", str(tmp_path / "a")]) == 0
    env = seen["env"]
    assert (env.contact_model, env.sim_dt, env.decimation) == ("stance", 0.0025, 8)
    assert (env.solver_iterations, env.solver_ls_iterations) == (8, 16)
    assert not env.float64_physics and switched == [False]
    assert main("flat", "", ["--feet", "aof", "--float64-physics", "--out", str(tmp_path / "b")]) == 0
    assert seen["env"].float64_physics and switched == [False, True]
    assert (seen["env"].solver_iterations, seen["env"].solver_ls_iterations) == (16, 16)  # float64's minimum
    assert main("flat", "", ["--feet", "ball", "--contact-model", "fast", "--out", str(tmp_path / "c")]) == 0
    env = seen["env"]
    assert (env.contact_model, env.sim_dt, env.decimation, env.solver_iterations, env.solver_ls_iterations) == (
        "fast",
        0.005,
        4,
        4,
        8,
    )
    run, cfg, _ = written_run
    assert cfg.contact_model == "stance"
    capsys.readouterr()
    assert main("flat", "", ["--out", str(run), "--resume", "--contact-model", "fast"]) == 2
    assert "--contact-model fast differs from the run's stance" in capsys.readouterr().err


@pytest.mark.slow  # a subprocess (x64 is process-wide): a tiny ball run, about 2 minutes
@pytest.mark.timeout(900)  # explicit budget: several times its time on 2 quiet cores
def test_training_with_float64_physics_keeps_the_networks_float32(built, tmp_path):
    """--float64-physics --contact-model stance: MJX steps in float64 (EnvConfig.float64_physics)
    while PPO's side stays float32 (the environment's policy_side, Brax's bookkeeping through
    PolicySideWrapper, and float32 network parameters: Brax makes its log-std float64 under x64,
    which made Adam's moments float64 and broke PPO's minibatch scan). The run ends, its saved
    configuration says float64, the saved networks' parameters are float32 and the policy acts.
    (Brax's observation normaliser keeps its running statistics in float64 under x64: type-stable,
    and the ONNX export casts it.)"""
    script = (
        "import sys, jax, numpy as np\n"
        "from footforge.cli.train import main\n"
        "code = main('flat', 'test', sys.argv[1:])\n"
        "assert code == 0, code\n"
        "assert jax.config.read('jax_enable_x64')\n"
        "from footforge.rl.train import load_policy\n"
        "policy, config, _ = load_policy(sys.argv[sys.argv.index('--out') + 1] + '/policy')\n"
        "assert config.float64_physics and config.contact_model == 'stance'\n"
        "from footforge.rl.train import load_policy_parameters\n"
        "saved = load_policy_parameters(sys.argv[sys.argv.index('--out') + 1] + '/policy').params\n"
        "leaves = jax.tree_util.tree_leaves(saved[1:])  # policy and value networks (saved[0]: the normaliser)\n"
        "print('PARAMS', sorted({str(x.dtype) for x in leaves}))\n"
        "from footforge.envs import observation_layout\n"
        "n = observation_layout.size(config, 0)  # 48 + the flat task's 12 PD targets\n"
        "action = policy(jax.numpy.zeros(n, jax.numpy.float32), jax.random.PRNGKey(0))[0]\n"
        "print('ACTION', action.shape, bool(jax.numpy.isfinite(action).all()))\n"
    )
    run = subprocess.run(
        [
            sys.executable,
            "-W",
            "error:scatter inputs have incompatible types:FutureWarning",
            "-c",
            script,
            "--feet",
            "ball",
            "--contact-model",
            "stance",
            "--float64-physics",
            "--build-root",
            str(built["ball"][0].parent),
            "--num-envs",
            "8",
            "--timesteps",
            "600",
            "--unroll-length",
            "4",
            "--batch-size",
            "8",
            "--minibatches",
            "1",
            "--eval-envs",
            "4",
            "--checkpoint-every",
            "300",
            "--no-evaluations",
            "--no-compile-cache",
            "--out",
            str(tmp_path / "run"),
        ],
        capture_output=True,
        text=True,
        timeout=1500,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    assert "PARAMS ['float32']" in run.stdout and "ACTION (12,) True" in run.stdout


# --- what training says before it compiles (issue: "training says what it does") ---


def test_planned_steps_round_up_to_whole_iterations_in_every_epoch():
    """Brax runs the same whole number of iterations in each epoch: 1,000 steps of 32-step
    iterations with checkpoints every 32 steps are 32 epochs of one iteration (1,024); with one
    epoch of 98,304-step iterations, one iteration."""
    from footforge.rl import train

    tiny = PPOConfig(**(SMALL_PPO | {"num_timesteps": 1000}))
    assert train.steps_per_iteration(tiny) == 32 and train.planned_steps(tiny) == 1024
    assert (
        train.planned_steps(
            PPOConfig(num_timesteps=1000, num_envs=2048, batch_size=512, num_minibatches=4, unroll_length=48)
        )
        == 98_304
    )
    assert train.planned_steps(replace_ppo(tiny, num_timesteps=96)) == 96  # whole already: unchanged
    assert train.planned_steps(replace_ppo(tiny, num_timesteps=96), done=64) == 96
    assert train.planned_steps(replace_ppo(tiny, num_timesteps=96), done=96) == 96  # nothing left
    # A checkpoint every 2.625 iterations (the CPU's 258,048 steps, the rough task's 98,304-step
    # iterations), 5.31 M of 200 M done: epochs of 2 iterations end within one iteration of the total,
    # where epochs of 258,048 steps rounded up to 3 iterations each planned 235 M.
    rough = PPOConfig(num_timesteps=200_000_000, checkpoint_every_steps=258_048)
    iteration = train.steps_per_iteration(rough)
    assert iteration == 98_304
    planned = train.planned_steps(rough, done=5_308_416)
    assert 200_000_000 <= planned < 200_000_000 + 2 * iteration, planned
    assert train.training_epochs(rough, done=5_308_416) * 2 * iteration == planned - 5_308_416
    # The `cpu` preset's flat run (checkpoints every 42 iterations of 6,144 steps): 10.06 M, as trained.
    from footforge.rl import presets

    _, flat = presets.resolve("flat", "aof", "B", "cpu")
    assert train.planned_steps(flat) == 10_063_872 and train.training_epochs(flat) == 39


def test_a_new_run_announces_device_steps_and_rounding_before_compiling(built, tmp_path, monkeypatch, capsys):
    from footforge.cli.train import main

    seen = _capture_train(monkeypatch)
    assert (
        main(
            "flat",
            "",
            [
                "--feet",
                "ball",
                "--build-root",
                str(built["ball"][0].parent),
                "--out",
                str(tmp_path / "run"),
                *TINY,
                "--timesteps",
                "1000",
            ],
            prog="footforge train flat",
        )
        == 0
    )
    out = capsys.readouterr().out
    assert (
        "footforge train flat: ball feet, policy B, 8 robots on cpu (1 x cpu); steps 0 -> 1,024 (--timesteps "
        "1,000 rounded up to whole PPO iterations of 32 steps" in out
    )
    assert "warning" not in out and seen["ppo"].num_timesteps == 1000
    assert (
        main(
            "flat",
            "",
            [
                "--feet",
                "ball",
                "--build-root",
                str(built["ball"][0].parent),
                "--out",
                str(tmp_path / "big"),
                "--num-envs",
                "1024",
                "--batch-size",
                "256",
            ],
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "warning: 1,024 robots on a CPU: one iteration of 49,152 steps takes about" in out
    assert "A CPU-sized run: --preset cpu" in out


def test_evaluation_robots_default_to_no_more_than_the_training_robots(built, tmp_path, monkeypatch):
    from footforge.cli.train import main

    seen = _capture_train(monkeypatch)
    root = ["--feet", "ball", "--build-root", str(built["ball"][0].parent)]
    assert main("flat", "", [*root, "--out", str(tmp_path / "a"), "--num-envs", "16", "--batch-size", "8"]) == 0
    assert seen["ppo"].num_eval_envs == 16
    assert main("flat", "", [*root, "--out", str(tmp_path / "b")]) == 0
    assert seen["ppo"].num_eval_envs == 128
    assert (
        main(
            "flat",
            "",
            [*root, "--out", str(tmp_path / "c"), "--num-envs", "16", "--batch-size", "8", "--eval-envs", "32"],
        )
        == 0
    )
    assert seen["ppo"].num_eval_envs == 32


def test_resuming_a_complete_run_says_so_and_trains_nothing(written_run, monkeypatch, capsys):
    from footforge.cli.train import main

    run, _, _ = written_run  # checkpoints at 32 and 64
    seen = _capture_train(monkeypatch)
    assert main("flat", "", ["--out", str(run), "--resume", "--timesteps", "64", "--shorten"]) == 0
    out = capsys.readouterr().out
    assert "already complete at step 64 (of 64); pass --timesteps with a larger total to extend it" in out
    assert not seen


def test_resume_keeps_a_run_s_no_evaluations(written_run, monkeypatch, capsys):
    from footforge.cli.train import main

    run, _, _ = written_run
    config = json.loads((run / "config.json").read_text())
    (run / "config.json").write_text(json.dumps(config | {"evaluations": False}))
    seen = _capture_train(monkeypatch)
    assert main("flat", "", ["--out", str(run), "--resume"]) == 0
    assert seen["kwargs"]["evaluate"] is False
    assert "started with --no-evaluations and continues without them" in capsys.readouterr().err
    assert main("flat", "", ["--out", str(run), "--resume", "--evaluations"]) == 0
    assert seen["kwargs"]["evaluate"] is True
    (run / "config.json").write_text(json.dumps(config))  # runs from before the key: evaluated
    assert main("flat", "", ["--out", str(run), "--resume"]) == 0
    assert seen["kwargs"]["evaluate"] is True


def test_train_records_whether_it_evaluates(written_run, tmp_path, monkeypatch):
    from brax.training.agents.ppo import train as ppo_train

    from footforge.rl import train

    _, cfg, ppo = written_run
    monkeypatch.setattr(ppo_train, "train", lambda **kwargs: None)
    train.train(cfg, ppo, tmp_path / "quiet", evaluate=False, notice=lambda text: None)
    assert json.loads((tmp_path / "quiet" / "config.json").read_text())["evaluations"] is False


def test_progress_before_any_episode_ends_shows_no_nan():
    import io

    from rich.console import Console

    from footforge.cli.train import _Reporter

    log = io.StringIO()
    with _Reporter(Console(file=log), "rough", 1000) as report:
        report(32, 1000, {"episode/length": float("nan")}, True)
        report(64, 1000, {"episode/length": 250.0, "episode/error/lin_vel_x_per_step": 0.5}, True)
    lines = log.getvalue().splitlines()
    assert "nan" not in log.getvalue()
    assert "training: no episode has ended yet" in lines[1]
    assert "training episodes: length   250  vx error 0.500 m/s" in lines[2] and "terrain level" not in lines[2]


def test_a_run_stopped_before_its_first_checkpoint_starts_again_with_the_same_command(written_run, tmp_path):
    """Interrupted while compiling: the folder holds a run with no checkpoint. Running the same
    command starts it again (nothing to continue); --resume still says there is nothing to resume."""
    import shutil

    from footforge.rl import train

    run, _, _ = written_run
    shutil.rmtree(run / "checkpoints")
    (run / "notes.txt").write_text("mine")
    messages = []
    train.prepare_run_dir(run, notice=messages.append)
    assert "reached no checkpoint, so it starts again" in messages[0]
    assert not (run / "config.json").exists() and (run / "notes.txt").read_text() == "mine"


def _interrupting(signum):
    from footforge.rl import train as train_lib

    def interrupted(*args, **kwargs):
        if signum == signal.SIGINT:
            raise KeyboardInterrupt  # what Python makes of Ctrl-C
        os.kill(os.getpid(), signum)
        time.sleep(5)  # the handler interrupts this
        raise AssertionError("the signal did not interrupt training")

    return train_lib, interrupted


@pytest.mark.parametrize(
    "signum, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")]
)
def test_an_interrupt_names_only_complete_checkpoints_and_exits_as_shells_expect(
    written_run, monkeypatch, capsys, signum, code, word
):
    """Ctrl-C exits 130 and SIGTERM 143 (128 + the signal). A checkpoint whose manifest was not yet
    written when the run stopped (orbax's files there, the manifest not) is not named as kept, and
    a resume does not start from it."""
    from footforge.cli import train as train_cli
    from footforge.rl import train

    run, _, _ = written_run
    (run / "checkpoints" / f"{64:012d}" / train.CHECKPOINT_MANIFEST).unlink()  # its write cut short
    module, interrupted = _interrupting(signum)
    monkeypatch.setattr(module, "train", interrupted)
    assert train_cli.main("flat", "test", ["--out", str(run), "--resume"]) == code
    err = capsys.readouterr().err
    assert f"footforge train flat: {word}; {run} keeps its checkpoints up to step 32: continue with --resume" in err, (
        err
    )
    assert train.latest_intact_checkpoint(run)[0] == 32


def test_a_shorter_total_on_resume_is_refused_unless_asked(written_run, monkeypatch, capsys):
    """--resume --timesteps below the run's total (96) would silently cut the run short: exit 2,
    naming --shorten; with --shorten it is accepted. --shorten alone is a usage error."""
    from footforge.cli.train import main

    run, _, _ = written_run
    seen = _capture_train(monkeypatch)
    assert main("flat", "", ["--out", str(run), "--resume", "--timesteps", "80"]) == 2
    err = capsys.readouterr().err
    assert "--timesteps 80 is below the run's total of 96" in err and "--shorten" in err and not seen
    assert main("flat", "", ["--out", str(run), "--resume", "--shorten"]) == 2
    assert "--shorten goes with --resume --timesteps" in capsys.readouterr().err and not seen
    assert main("flat", "", ["--out", str(run), "--resume", "--timesteps", "80", "--shorten"]) == 0
    assert seen["ppo"].num_timesteps == 80
    assert main("flat", "", ["--out", str(run), "--resume", "--timesteps", "160"]) == 0  # extending needs nothing
    assert seen["ppo"].num_timesteps == 160


def _at_total(run):
    """The written run as if its total were its last checkpoint's step (64): killed during its final
    evaluation, after that checkpoint and before policy/."""
    config = json.loads((run / "config.json").read_text())
    config["ppo"]["num_timesteps"] = 64
    (run / "config.json").write_text(json.dumps(config))


def test_a_run_killed_before_its_policy_is_finished_by_resume(written_run, capsys):
    """A run stopped after its last checkpoint but before policy/ (issue: `--resume` said "already
    complete" and wrote nothing, export refused the run): --resume writes policy/ from the newest
    intact checkpoint; a damaged policy/ is rewritten the same way; a complete one is left."""
    from footforge.cli.train import main
    from footforge.rl import train

    run, _, _ = written_run
    _at_total(run)
    assert not (run / "policy").exists()
    assert main("flat", "", ["--out", str(run), "--resume"]) == 0
    out = capsys.readouterr().out
    assert (
        "it has no policy/ yet: wrote" in out and "from checkpoint 64" in out and "already complete at step 64" in out
    )
    assert train.policy_meta(run / "policy")["global_step"] == 64 and train.policy_problem(run) is None
    np.testing.assert_array_equal(
        _kernel(train.load_policy_parameters(run / "policy").params), _kernel(_params(64, PPOConfig(**SMALL_PPO)))
    )
    before = (run / "policy" / "footforge.json").stat().st_mtime_ns
    assert main("flat", "", ["--out", str(run), "--resume"]) == 0  # nothing to do: policy/ left as it is
    assert "wrote" not in capsys.readouterr().out and (run / "policy" / "footforge.json").stat().st_mtime_ns == before
    _truncate_data(run / "policy")
    assert "damaged" in train.policy_problem(run)
    assert main("flat", "", ["--out", str(run), "--resume"]) == 0
    assert "its policy/ is damaged" in capsys.readouterr().out and train.policy_problem(run) is None


def test_a_run_without_a_policy_is_used_through_its_newest_intact_checkpoint(
    written_run, tmp_path, capsys, monkeypatch
):
    """export (and evaluate, play: the same policy_folder) of a run with checkpoints but no policy/,
    or a damaged one, uses its newest intact checkpoint and says so; a checkpoint folder is a policy
    too, its configs read from the run; a damaged policy's fix names commands that work."""
    from footforge.cli.main import main
    from footforge.cli.train import main as train_main
    from footforge.rl import train

    run, cfg, _ = written_run
    newest = run / "checkpoints" / f"{64:012d}"
    assert train.policy_folder(run) == newest
    monkeypatch.chdir(tmp_path)
    assert main(["export", str(run)]) == 0
    captured = capsys.readouterr()
    assert f"{run}: it has no policy/ yet; using its newest intact checkpoint, step 64" in captured.err
    assert (tmp_path / "run_step64.onnx").is_file()  # named after the run and step, in the current folder
    (tmp_path / "run_step64.onnx").unlink()
    assert main(["export", str(newest)]) == 0 and (tmp_path / "run_step64.onnx").is_file()
    saved = train.load_policy_parameters(newest)
    assert saved.global_step == 64 and saved.env == cfg
    assert train.load_policy_config(run) == cfg
    _truncate_data(newest)  # then the newest intact one is 32
    assert train.policy_folder(run) == run / "checkpoints" / f"{32:012d}"
    assert main(["export", str(newest), "--out", str(tmp_path / "x.onnx")]) == 2
    err = capsys.readouterr().err
    assert "the checkpoint is damaged or incomplete" in err and f"{32:012d}" in err
    # A damaged policy/: the run folder falls back to a checkpoint; the policy folder itself is
    # refused with fixes that work.
    _at_total(run)
    assert train_main("flat", "", ["--out", str(run), "--resume", "--timesteps", "32", "--shorten"]) == 0
    assert train.policy_meta(run / "policy")["global_step"] == 32
    _truncate_data(run / "policy")
    assert train.policy_folder(run) == run / "checkpoints" / f"{32:012d}"
    capsys.readouterr()
    assert main(["export", str(run / "policy"), "--out", str(tmp_path / "y.onnx")]) == 2
    err = capsys.readouterr().err
    assert "the policy is damaged" in err and f"pass the run folder {run}" in err
    assert f"footforge train flat --out {run} --resume" in err
    assert main(["export", str(run), "--out", str(tmp_path / "y.onnx")]) == 0
    assert "its policy/ is damaged; using its newest intact checkpoint, step 32" in capsys.readouterr().err


def _curve_rows(run):
    return [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]


def _write_curve(run, rows):
    (run / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))


def _resumed_ppo(calls):
    """Brax's PPO as train() calls it on a resume: the initial evaluation (step 0), a training
    log, then one epoch's checkpoint and evaluation."""

    def run(ppo_train, env, env_config, ppo, remaining, epochs, restore, resumes, log, save, *rest):
        calls.append(remaining)
        log(0, {"eval/episode_reward": 0.5})
        log(remaining // 2, {"episode/length": 3.0})
        save(remaining, None, restore)
        log(remaining, {"eval/episode_reward": 1.0, "eval/walltime": 0.1, "training/sps": 10.0})

    return run


@pytest.mark.parametrize(
    "killed", ["after the evaluation of 64", "before the evaluation of 64", "after a damaged checkpoint 64"]
)
def test_curves_continue_from_the_resumed_step(written_run, monkeypatch, killed):
    """The curve after a kill and a resume has one increasing step axis and cumulative wall time:
    rows the killed call logged after the restored checkpoint move to metrics.set_aside.jsonl;
    the resumed call's first evaluation is written only if the checkpoint's was not. Kills at three
    points: after the last checkpoint's evaluation and a training log past it; between a
    checkpoint and its evaluation; after a checkpoint later found damaged (resumed from 32)."""
    from footforge.rl import train

    run, cfg, ppo = written_run
    rows = [
        {"global_step": 0, "wall_s": 1.0, "eval/episode_reward": 0.1},
        {"global_step": 16, "wall_s": 2.0, "episode/length": 2.0},
        {"global_step": 32, "wall_s": 3.0, "eval/episode_reward": 0.2},
        {"global_step": 48, "wall_s": 4.0, "episode/length": 2.5},
        {"global_step": 64, "wall_s": 5.0, "eval/episode_reward": 0.3},
        {"global_step": 80, "wall_s": 6.0, "episode/length": 2.7},
    ]
    if killed == "before the evaluation of 64":
        rows = rows[:4]
    _write_curve(run, rows)
    (run / "progress.json").write_text(
        json.dumps({"global_step": 64, "resumes": 0, "metrics": {}, "wall_s_total": 5.0})
    )
    if killed == "after a damaged checkpoint 64":
        _truncate_data(run / "checkpoints" / f"{64:012d}")
    calls = []
    monkeypatch.setattr(train, "_run_ppo", _resumed_ppo(calls))
    train.train(cfg, ppo, run, resume=True, notice=lambda text: None)
    curve = _curve_rows(run)
    steps = [r["global_step"] for r in curve]
    walls = [r["wall_s"] for r in curve]
    assert steps == sorted(steps) and walls == sorted(walls), curve
    restored = 32 if killed == "after a damaged checkpoint 64" else 64
    assert all(r["wall_s"] >= 5.0 for r in curve if r["global_step"] > restored)  # the earlier calls' time counts
    aside = (
        [json.loads(line) for line in (run / "metrics.set_aside.jsonl").read_text().splitlines()]
        if (run / "metrics.set_aside.jsonl").exists()
        else []
    )
    assert all(r["set_aside_by_resume"] == 1 for r in aside)
    expected = {
        "after the evaluation of 64": ([0, 16, 32, 48, 64, 80, 96], [80]),
        "before the evaluation of 64": ([0, 16, 32, 48, 64, 80, 96], []),  # 64: the resumed call's evaluation
        "after a damaged checkpoint 64": ([0, 16, 32, 64, 96], [48, 64, 80]),
    }[killed]
    assert (steps, [r["global_step"] for r in aside]) == expected, (curve, aside)
    evaluations = [r["global_step"] for r in curve if "eval/episode_reward" in r]
    assert len(evaluations) == len(set(evaluations))  # no step evaluated twice


def test_a_kept_run_holds_its_newest_checkpoint_and_gzipped_curve_and_resumes_from_them(written_run, monkeypatch):
    """keep_run (scripts/keep_run.py) copies a run still in training into a policy folder as git keeps
    it: the newest intact checkpoint alone (the one kept before goes), the curve gzipped to the same
    rows, the folder's own evaluation/ untouched. `--resume` from that folder unpacks the curve and
    continues it: the kept rows, then the resumed call's, and no gzipped copy left beside them."""
    import gzip
    import shutil

    from footforge.rl import train
    from footforge.rl.checkpoints import checkpoint_problem
    from footforge.rl.kept_run import keep_run

    run, cfg, ppo = written_run
    rows = [{"global_step": s, "wall_s": 1.0 + s, "episode/length": 2.0 + s} for s in (0, 16, 32, 48, 64)]
    _write_curve(run, rows)
    dest = run.parent / "kept"
    (dest / "checkpoints").mkdir(parents=True)
    shutil.copytree(run / "checkpoints" / f"{32:012d}", dest / "checkpoints" / f"{32:012d}")  # kept last time
    (dest / "config.json").write_text((run / "config.json").read_text())
    (dest / "evaluation").mkdir()
    (dest / "evaluation" / "metrics.json").write_text("{}")
    for step in (64, 16):  # killed keep_runs' copies (no such PID) of this checkpoint and of an older one
        (dest / "checkpoints" / f".{step:012d}.tmp-999999999-x1").mkdir()
    written = keep_run(run, dest)
    assert written[-1] == f"checkpoints/{64:012d}" and "metrics.jsonl.gz" in written
    assert sorted(p.name for p in (dest / "checkpoints").iterdir()) == [f"{64:012d}"]  # the leftovers went too
    source, copy = run / "checkpoints" / f"{64:012d}", dest / "checkpoints" / f"{64:012d}"
    files = [sorted(p.relative_to(folder) for p in folder.rglob("*")) for folder in (source, copy)]
    assert files[0] == files[1]  # the run's checkpoint as it was: no marker or other file added
    assert not (dest / "metrics.jsonl").exists() and not (dest / "tensorboard").exists()
    assert gzip.decompress((dest / "metrics.jsonl.gz").read_bytes()) == (run / "metrics.jsonl").read_bytes()
    assert (dest / "evaluation" / "metrics.json").read_text() == "{}"
    assert checkpoint_problem(dest / "checkpoints" / f"{64:012d}") is None
    calls = []
    monkeypatch.setattr(train, "_run_ppo", _resumed_ppo(calls))
    train.train(cfg, ppo, dest, resume=True, notice=lambda text: None)
    assert not (dest / "metrics.jsonl.gz").exists()
    curve = _curve_rows(dest)
    assert curve[: len(rows)] == rows and [r["global_step"] for r in curve[len(rows) :]] == [64, 80, 96]
    assert calls == [ppo.num_timesteps - 64]


def test_a_finished_run_is_kept_with_its_policy_in_place_of_the_checkpoint(written_run):
    """Once a run reached its total steps, keep_run keeps its policy/ and removes the checkpoint the
    folder kept while it trained: the weights once."""
    import shutil

    from footforge.rl import train
    from footforge.rl.kept_run import keep_run

    run, cfg, ppo = written_run
    dest = run.parent / "kept"
    keep_run(run, dest)  # in training: progress at 64 of 96 steps
    assert (dest / "checkpoints" / f"{64:012d}").is_dir() and not (dest / "policy").exists()
    (run / "progress.json").write_text(json.dumps({"global_step": ppo.num_timesteps, "resumes": 0, "metrics": {}}))
    shutil.rmtree(run / "policy", ignore_errors=True)
    with pytest.raises(InputError, match="policy/ is not the final one"):
        keep_run(run, dest)  # finished but never wrote policy/: refused, naming the resume that writes it
    assert train.finish_run(run) is not None  # policy/ from the newest checkpoint
    assert keep_run(run, dest)[-1] == "policy"
    assert (dest / "policy" / "footforge.json").is_file() and not (dest / "checkpoints").exists()


def test_a_resumed_rough_run_starts_its_robots_where_its_curriculum_stood(written_run, monkeypatch):
    """A rough run resumed from its checkpoint at step 64 draws its robots' first levels from the level
    shares its curve last logged at or before 64 (CurriculumConfig.initial_level_shares), not from
    0..initial_max_level again; rows of other kinds, rows past the checkpoint and cut lines are passed
    over; config.json keeps the configuration the run began with."""
    from dataclasses import replace

    from footforge.rl import train

    run, cfg, ppo = written_run
    rough = replace(envs.default_config("rough", "ball", "P"), build_dir=cfg.build_dir)
    (run / "config.json").write_text(json.dumps({"env": to_dict(rough), "ppo": to_dict(ppo)}))

    def shares(**at):
        return {f"episode/terrain/at_level_{k}_per_step": at.get(f"l{k}", 0.0) for k in range(10)}

    _write_curve(
        run,
        [
            {"global_step": 16, **shares(l1=1.0)},
            {"global_step": 48, **shares(l2=0.25, l3=0.75)},
            {"global_step": 56, "eval/episode_reward": 1.0},
            {"global_step": 80, **shares(l9=1.0)},  # logged after the checkpoint: set aside
        ],
    )
    with open(run / "metrics.jsonl", "a") as f:
        f.write('{"global_step": 60, "episode/terrain/at_lev')  # cut short by a kill
    made, notes = [], []

    class Made(Exception):
        pass

    def capture(config):
        made.append(config)
        raise Made

    monkeypatch.setattr(envs, "from_config", capture)
    with pytest.raises(Made):
        train.train(rough, ppo, run, resume=True, notice=notes.append)
    assert made[0].curriculum.initial_level_shares == (0.0, 0.0, 0.25, 0.75, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert any("mean level 2.75" in n for n in notes), notes
    assert json.loads((run / "config.json").read_text())["env"]["curriculum"]["initial_level_shares"] is None
    assert train.logged_level_shares(train.curve_rows(run, 40), 10) == (0.0, 1.0) + (0.0,) * 8
    assert train.logged_level_shares(train.curve_rows(run, 8), 10) is None
    assert train.logged_level_shares(train.curve_rows(run, 64), 6) is None


def test_a_resumed_rough_run_restores_its_curriculum_kind_by_kind(written_run, monkeypatch):
    """The steps the episodes spent on each terrain kind and level, logged by the rough environment
    (KIND_LEVEL_STEPS), are kept out of the curve and TensorBoard and recorded with each checkpoint's
    progress.json; a resume from that checkpoint starts each kind's robots on that kind's levels, in
    proportion to those steps (CurriculumConfig.initial_level_shares_by_kind), beside the all-kinds shares of
    the curve; a checkpoint written before the resumed call's first log records the shares it resumed from."""
    from dataclasses import replace
    from types import SimpleNamespace

    from footforge.envs.terrain import KINDS, TerrainConfig, generate
    from footforge.rl import train

    run, cfg, ppo = written_run
    rough = replace(envs.default_config("rough", "ball", "P"), build_dir=cfg.build_dir)
    (run / "config.json").write_text(json.dumps({"env": to_dict(rough), "ppo": to_dict(ppo)}))
    at_3 = {f"episode/terrain/at_level_{k}_per_step": float(k == 3) for k in range(10)}
    _write_curve(run, [{"global_step": 48, **at_3}])

    def by_kind(where: dict) -> dict:  # {(kind, level): share}
        return {train.KIND_LEVEL_STEPS.format(kind, k): where.get((kind, k), 0.0) for kind in KINDS for k in range(10)}

    recorded = by_kind({("stairs_up", 1): 100.0, ("smooth_slope", 6): 200.0, ("smooth_slope", 7): 100.0})
    (run / "progress.json").write_text(json.dumps({"global_step": 64, "resumes": 0, "metrics": recorded}))
    made, notes = [], []
    small = generate(TerrainConfig(num_levels=2, num_columns=6, tile_size_m=2.0, border_m=1.0, platform_m=1.0))

    def make(config):
        made.append(config)
        return SimpleNamespace(observation_size=48, action_size=12, terrain=small)

    logged = by_kind({("discrete", 2): 640.0})

    seeded = []

    def fake_ppo(ppo_train, env, env_config, ppo, remaining, epochs, restore, resumes, log, save, *rest):
        save(8, None, restore)  # before any log: the shares it resumed from
        seeded.append(json.loads((run / "progress.json").read_text()))
        log(16, {"episode/terrain/at_level_2_per_step": 1.0, "episode/length": 5.0, **logged})
        log(16, {"eval/episode_reward": 1.0, "eval/episode_terrain/discrete/steps_at_level_2_std": 1.0})
        save(remaining, None, restore)

    monkeypatch.setattr(envs, "from_config", make)
    monkeypatch.setattr(train, "_run_ppo", fake_ppo)
    train.train(rough, ppo, run, resume=True, notice=notes.append)
    rows = dict(zip(KINDS, made[0].curriculum.initial_level_shares_by_kind))
    assert rows["stairs_up"] == (0.0, 0.25) + (0.0,) * 8 and rows["smooth_slope"][6:8] == (0.5, 0.25)
    assert sum(map(sum, rows.values())) == 1.0
    again = train.checkpoint_level_shares_by_kind(seeded[0], 72, 10)
    assert seeded[0]["global_step"] == 72 and again == made[0].curriculum.initial_level_shares_by_kind
    assert made[0].curriculum.initial_level_shares == (0.0, 0.0, 0.0, 1.0) + (0.0,) * 6
    assert any("kind by kind" in n and "smooth_slope 6.33" in n and "stairs_up 1.00" in n for n in notes), notes
    curve = _curve_rows(run)
    assert curve[-2]["episode/terrain/at_level_2_per_step"] == 1.0 and "eval/episode_reward" in curve[-1]
    assert not [k for row in curve for k in row if "/steps_at_level_" in k]
    progress = json.loads((run / "progress.json").read_text())
    assert progress["global_step"] == 96 and {k: progress["metrics"][k] for k in logged} == logged
    assert json.loads((run / "config.json").read_text())["env"]["curriculum"]["initial_level_shares_by_kind"] is None
    # What the next resume takes: the shares recorded at its checkpoint's step, none from another step.
    assert dict(zip(KINDS, train.checkpoint_level_shares_by_kind(progress, 96, 10)))["discrete"][2] == 1.0
    assert train.checkpoint_level_shares_by_kind(progress, 64, 10) is None  # an older checkpoint restored
    assert train.checkpoint_level_shares_by_kind(progress, 96, 9) is None  # another terrain's level count
    assert train.checkpoint_level_shares_by_kind({"global_step": 96, "metrics": {}}, 96, 10) is None
    negative = progress | {"metrics": logged | {train.KIND_LEVEL_STEPS.format("discrete", 0): -1.0}}
    assert train.checkpoint_level_shares_by_kind(negative, 96, 10) is None


def test_a_resume_goes_on_with_the_adaptive_learning_rate_it_had(written_run, monkeypatch):
    """Brax cannot restore its optimiser state, so the adaptive-KL learning rate would restart at
    PPOConfig.learning_rate on each resume; it goes on from the rate the curve last logged at or before
    the restored checkpoint instead (rows past it, rows without a rate and cut lines passed over), and
    config.json keeps the run's own. Without adaptive KL the configured rate stays."""
    from dataclasses import replace

    from footforge.rl import train

    run, cfg, ppo = written_run
    _write_curve(
        run,
        [
            {"global_step": 16, "training/learning_rate": 4e-4},
            {"global_step": 48, "training/learning_rate": 5e-5, "episode/length": 3.0},
            {"global_step": 56, "eval/episode_reward": 1.0},
            {"global_step": 80, "training/learning_rate": 2e-3},  # after the checkpoint: set aside
        ],
    )
    given = []

    def run_ppo(ppo_train, env, env_config, ppo_used, *rest):
        given.append(ppo_used.learning_rate)

    monkeypatch.setattr(train, "_run_ppo", run_ppo)
    notes = []
    train.train(cfg, ppo, run, resume=True, notice=notes.append)
    assert ppo.adaptive_kl and given == [5e-5], given
    assert any("learning rate goes on from 5e-05" in n for n in notes), notes
    assert json.loads((run / "config.json").read_text())["ppo"]["learning_rate"] == ppo.learning_rate
    assert train.logged_learning_rate(train.curve_rows(run, 20)) == 4e-4
    assert train.logged_learning_rate(train.curve_rows(run, 8)) is None
    fixed = replace(ppo, adaptive_kl=0.0)
    (run / "config.json").write_text(json.dumps({"env": to_dict(cfg), "ppo": to_dict(fixed)}))
    train.train(cfg, fixed, run, resume=True, notice=notes.append)
    assert given[-1] == fixed.learning_rate


def test_first_levels_follow_the_shares_a_resume_gives():
    """curriculum.first_levels draws from initial_level_shares where given: the levels' frequencies over
    20,000 robots within 1.5 % of the shares, none on a level of share 0."""
    from dataclasses import replace

    from footforge.envs import curriculum
    from footforge.envs.config import CurriculumConfig
    from footforge.envs.terrain import TerrainConfig

    t = TerrainConfig()
    shares = (0.1, 0.0, 0.4, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.2)
    c = replace(CurriculumConfig(), initial_level_shares=shares)
    level, _ = curriculum.first_levels(jax.random.PRNGKey(3), c, t, (20_000,))
    counts = np.bincount(np.asarray(level), minlength=t.num_levels) / 20_000
    np.testing.assert_allclose(counts, shares, atol=0.015)
    assert counts[1] == counts[3] == counts[8] == 0.0


def test_a_kept_curve_that_cannot_be_continued_is_refused_naming_the_file(written_run):
    """Two copies of the curve (metrics.jsonl and metrics.jsonl.gz) are refused before any work, and a
    gzipped curve that is not gzip is an input error naming the file, not a traceback."""
    from footforge.rl import train
    from footforge.rl.kept_run import keep_run

    run, cfg, ppo = written_run
    (run / "metrics.jsonl.gz").write_bytes(b"not gzip")
    with pytest.raises(InputError, match="two copies of the learning curve"):
        train.prepare_run_dir(run, resume=True)
    (run / "metrics.jsonl").unlink()
    with pytest.raises(InputError, match="gzipped learning curve cannot be read") as caught:
        train.continue_curve(run, 64, 1)
    assert caught.value.file == str(run / "metrics.jsonl.gz")
    (run.parent / "theirs").mkdir()
    (run.parent / "theirs" / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="not a footforge run's"):
        keep_run(run, run.parent / "theirs")
    assert (run.parent / "theirs" / "notes.txt").read_text() == "mine"


def test_rough_runs_saved_before_the_sole_spheres_resume_on_boxes():
    """EnvConfig.heightfield_soles: a rough run's config.json from before the setting (the GPU
    campaign's rough_aof_P and _PH, the latter's now a record under benchmarks/) loads as 'box', as it
    trained; a new rough config is 'spheres'."""
    run = Path(__file__).parents[1] / "benchmarks/gpu_rough_campaign_2026-11-27/rough_aof_PH_run"
    saved = json.loads((run / "config.json").read_text())["env"]
    assert "heightfield_soles" not in saved and env_config_from_dict(saved).heightfield_soles == "box"
    assert envs.default_config("rough", "aof", "PH").heightfield_soles == "spheres"
    now = to_dict(envs.default_config("rough", "aof", "PH"))
    assert env_config_from_dict(json.loads(json.dumps(now))).heightfield_soles == "spheres"


def test_the_policy_s_initial_actions_are_as_small_as_its_output_scale_says():
    """PPOConfig.policy_output_init_scale scales the freshly initialised policy's output (mean)
    layer: over random observations the mean actions' spread is in proportion to the scale (the
    hidden layers are initialised alike for a seed), the default 0.01 making the untrained policy's
    mean actions a few hundredths, and the exploration deviation (init_noise_std) is left alone."""
    from brax.training.acme import running_statistics, specs

    from footforge.rl import train

    observations = jax.random.normal(jax.random.PRNGKey(1), (256, 48))

    def initial_actions(scale: float):
        ppo = PPOConfig(policy_output_init_scale=scale)
        nets = train.network_factory(ppo)(
            observation_size=48, action_size=12, preprocess_observations_fn=running_statistics.normalize
        )
        normaliser = running_statistics.init_state(specs.Array((48,), jp.dtype("float32")))
        params = nets.policy_network.init(jax.random.PRNGKey(0))
        mean, deviation = nets.policy_network.apply(normaliser, params, observations)
        return float(jp.std(mean)), np.asarray(deviation), ppo

    full, full_deviation, _ = initial_actions(1.0)
    tenth, tenth_deviation, _ = initial_actions(0.1)
    default, default_deviation, ppo = initial_actions(PPOConfig().policy_output_init_scale)
    assert ppo.policy_output_init_scale == 0.01
    assert 0.3 < full < 3.0, full  # a full-size layer: actions of order one
    assert tenth == pytest.approx(0.1 * full, rel=1e-3) and default == pytest.approx(0.01 * full, rel=1e-3)
    assert default < 0.05, default
    np.testing.assert_array_equal(default_deviation, full_deviation)
    np.testing.assert_array_equal(tenth_deviation, full_deviation)


def test_curve_rows_read_a_kept_gzipped_curve_where_the_plain_one_is_not_there(tmp_path):
    """A process that reads before process 0 unpacked a kept curve (continue_curve) reads the gzipped copy:
    the same rows up to the step, a cut line left out; an unreadable copy gives no rows (process 0 names it)."""
    import gzip

    from footforge.rl import train

    lines = [json.dumps({"global_step": s, "training/learning_rate": 1e-4 * s}) for s in (8, 16, 24)]
    (tmp_path / "metrics.jsonl.gz").write_bytes(gzip.compress(("\n".join(lines) + '\n{"global_st').encode()))
    assert [r["global_step"] for r in train.curve_rows(tmp_path, 16)] == [8, 16]
    assert train.logged_learning_rate(train.curve_rows(tmp_path, 16)) == pytest.approx(1.6e-3)
    (tmp_path / "metrics.jsonl.gz").write_bytes(b"not gzip")
    assert train.curve_rows(tmp_path, 16) == []


def test_a_policys_digest_is_of_its_parameters_not_of_where_it_lies(tmp_path):
    """policy_digest: a copy (with footforge's output marker) and the run folder around it give the policy's
    digest; a changed byte changes it."""
    import shutil

    from footforge.outputs import write_marker
    from footforge.rl.policy_files import policy_digest

    shipped = REPO / "policies/flat_aof_B/policy"
    copy = tmp_path / "run" / "policy"
    shutil.copytree(shipped, copy)
    write_marker(copy, "a copy")
    assert policy_digest(copy) == policy_digest(shipped) == policy_digest(REPO / "policies/flat_aof_B")
    meta = copy / "footforge.json"
    meta.write_bytes(meta.read_bytes() + b" ")
    assert policy_digest(copy) != policy_digest(shipped)
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no policy files"):
        policy_digest(tmp_path / "empty")
