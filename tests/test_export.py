"""`footforge export`: the ONNX policy computes what load_policy computes (onnxruntime against JAX
on random observations and on a recorded rollout), carries its deployment metadata, and bad input
is a one-line error with exit code 2 and nothing written."""

import json
import shutil
from dataclasses import replace

import jax
import jax.numpy as jp
import numpy as np
import onnx
import onnxruntime
import pytest

from footforge import constants as C, envs
from footforge.cli.main import main
from footforge.envs import observation_layout
from footforge.rl import train
from footforge.rl.train import PPOConfig, load_policy

TOLERANCE = 1e-5
"""Max abs difference of the actions, onnxruntime vs JAX (float32 rounding of a few hundred sums)."""


def _perturbed_policy(env_config, ppo, out_dir, observation_size, seed=0):
    """initial_policy's folder with non-trivial parameters: normaliser mean and std drawn at random
    (a fresh normaliser is mean 0, std 1, which would hide a missing or swapped normalisation) and
    random biases (fresh ones are zero)."""
    from brax.training.agents.ppo import checkpoint as brax_checkpoint

    rng = np.random.default_rng(seed)
    fresh = train.initial_policy(env_config, ppo, out_dir.with_name(out_dir.name + "_fresh"), observation_size)
    params = list(brax_checkpoint.load(str(fresh)))
    norm = params[0]

    def draw(mean_like):
        n = mean_like.shape[0]
        return jp.asarray(rng.normal(0.0, 0.5, n), jp.float32), jp.asarray(rng.uniform(0.2, 3.0, n), jp.float32)

    if isinstance(norm.mean, dict):
        drawn = {key: draw(value) for key, value in norm.mean.items()}
        params[0] = norm.replace(mean={k: m for k, (m, _) in drawn.items()}, std={k: s for k, (_, s) in drawn.items()})
    else:
        mean, std = draw(norm.mean)
        params[0] = norm.replace(mean=mean, std=std)
    params[1] = jax.tree.map(lambda x: x + jp.asarray(rng.normal(0.0, 0.1, x.shape), x.dtype), params[1])
    factory = train.network_factory(ppo, env_config.privileged_critic)
    staging = out_dir.with_name(out_dir.name + "_staging")
    brax_checkpoint.save(
        str(staging),
        0,
        tuple(params),
        brax_checkpoint.network_config(observation_size, 12, ppo.normalize_observations, factory),
    )
    shutil.copytree(staging / f"{0:012d}", out_dir)
    shutil.copy(fresh / "footforge.json", out_dir / "footforge.json")
    return out_dir


def _onnx_actions(path, obs):
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return session.run(["actions"], {"obs": np.asarray(obs, np.float32)})[0]


def _jax_actions(policy, obs, privileged_extra=0):
    obs = jp.asarray(obs, jp.float32)
    if privileged_extra:  # the critic's slice, which must not reach the policy
        obs = {"state": obs, "privileged_state": jp.concatenate([obs, jp.ones((obs.shape[0], privileged_extra))], 1)}
    action, _ = policy(obs, jax.random.PRNGKey(0))
    return np.asarray(action)


def _metadata(path):
    return {p.key: json.loads(p.value) for p in onnx.load(str(path)).metadata_props}


CASES = {  # (task, feet, policy, privileged critic, observation size of the policy)
    "flat_ball_B": ("flat", "ball", "B", False, 48),  # position actions: no PD targets observed
    "flat_aof_BH": ("flat", "aof", "BH", False, 48 + 2 * 16),
    "rough_aff_PH_privileged": ("rough", "aff", "PH", True, 48 + 140 + 2 * 8),
}


@pytest.mark.parametrize("case", CASES)
def test_onnx_matches_the_jax_policy_on_random_observations(tmp_path, capsys, case, monkeypatch):
    import footforge

    task, feet, policy_type, privileged, size = CASES[case]
    env_config = replace(envs.default_config(task, feet, policy_type), privileged_critic=privileged)
    ppo = PPOConfig(policy_hidden_layers=(32, 16, 8), value_hidden_layers=(8,), seed=3)
    obs_size = {"state": (size,), "privileged_state": (size + 20,)} if privileged else size
    policy_dir = _perturbed_policy(env_config, ppo, tmp_path / "policy", obs_size)
    monkeypatch.chdir(tmp_path)  # the default output goes to the current folder, named after the run
    code = main(["export", str(policy_dir)])
    text = capsys.readouterr()
    assert code == 0, text.err
    path = tmp_path / f"{tmp_path.name}.onnx"
    assert path.is_file() and path.name in text.out
    assert not list(policy_dir.glob("*.onnx"))  # never into the policy's own folder

    rng = np.random.default_rng(1)
    obs = np.concatenate([rng.normal(0.0, 1.0, (64, size)), rng.uniform(-5.0, 5.0, (64, size))]).astype(np.float32)
    policy, _, _ = load_policy(policy_dir, deterministic=True)
    expected = _jax_actions(policy, obs, 20 if privileged else 0)
    got = _onnx_actions(path, obs)
    assert got.shape == (128, 12)
    difference = float(np.abs(got - expected).max())
    print(f"{case}: max abs difference {difference:.3g}")
    assert difference <= TOLERANCE
    assert np.abs(expected).max() > 0.1  # the comparison is not between two near-zero outputs
    np.testing.assert_allclose(_onnx_actions(path, obs[:1]), got[:1], atol=TOLERANCE)  # dynamic batch

    meta = _metadata(path)
    assert (meta["task"], meta["feet"], meta["policy_type"]) == (task, feet, policy_type)
    assert meta["footforge_version"] == footforge.__version__ and meta["global_step"] == 0
    assert meta["joint_names"] == list(C.ACTUATED_JOINTS)
    assert meta["default_joint_angles_rad"] == [C.DEFAULT_JOINT_ANGLES_RAD[j] for j in C.ACTUATED_JOINTS]
    assert meta["action"]["model"] == env_config.action and meta["action"]["scale"] == env_config.action_scale
    assert meta["action"]["clip"] == env_config.action_clip
    assert (
        meta["pd_gains"]["kp_nm_per_rad"] == C.KP_NM_PER_RAD and meta["pd_gains"]["kd_nms_per_rad"] == C.KD_NMS_PER_RAD
    )
    assert meta["control_period_s"] == pytest.approx(env_config.sim_dt * env_config.decimation)
    layout = meta["observation"]["layout"]
    n_passive = (size - observation_layout.size(env_config, 0)) // 2
    assert [(s["name"], s["size"]) for s in layout] == observation_layout.layout(env_config, n_passive)
    assert [s["start"] for s in layout] == list(np.cumsum([0] + [s["size"] for s in layout])[:-1])
    assert meta["observation"]["size"] == size and meta["observation"]["clip"] == env_config.observations.clip
    scales = {s["name"]: s["scale"] for s in layout}
    assert scales["joint_vel"] == env_config.observations.joint_vel.scale
    assert scales["command"] == list(env_config.observations.command.scale)
    assert meta["network"]["policy_hidden_layers"] == [32, 16, 8] and meta["network"]["activation"] == "elu"


@pytest.fixture(scope="module")
def ball_build(tmp_path_factory):
    """The ball-foot build alone (a few seconds; the session's `built` builds every variant)."""
    from footforge.build import BuildOptions, build

    root = tmp_path_factory.mktemp("export_build")
    build(BuildOptions(variant="ball", out_dir=root / "ball", cache_dir=root / "coacd"))
    return root / "ball"


@pytest.mark.slow  # a recorded rollout of a shipped policy: about 30 s (random observations: the default run)
@pytest.mark.timeout(600)  # explicit budget: several times its time on 2 quiet cores
def test_onnx_matches_the_jax_policy_on_a_recorded_rollout(tmp_path, ball_build):
    """The flat ball B policy walks 40 policy steps in MJX under its JAX actions (pushed at once,
    under a command); onnxruntime, fed the recorded observations, gives the same actions."""
    env_config = replace(
        envs.default_config("flat", "ball", "B"),
        build_dir=str(ball_build),
        pushes=replace(envs.default_config("flat", "ball", "B").pushes, interval_s=0.2),
    )
    ppo = PPOConfig(policy_hidden_layers=(64, 32), value_hidden_layers=(8,))
    policy_dir = _perturbed_policy(env_config, ppo, tmp_path / "policy", observation_layout.size(env_config, 0), seed=5)
    out = tmp_path / "deploy" / "anymal.onnx"
    out.parent.mkdir()
    assert main(["export", str(policy_dir), "--out", str(out)]) == 0
    policy, _, _ = load_policy(policy_dir)
    env = envs.from_config(env_config)

    def one_step(state, key):
        action, _ = policy(state.obs, key)
        return env.step(state, action), (state.obs, action)

    @jax.jit
    def rollout(key):
        _, (obs, actions) = jax.lax.scan(one_step, env.reset(key), jax.random.split(key, 40))
        return obs, actions

    obs, actions = map(np.asarray, rollout(jax.random.PRNGKey(2)))
    assert np.isfinite(obs).all() and obs.std(axis=0).max() > 0.01  # the robot moved
    difference = float(np.abs(_onnx_actions(out, obs) - actions).max())
    print(f"rollout: max abs difference {difference:.3g}")
    assert difference <= TOLERANCE


def test_bad_input_is_a_one_line_error_and_writes_nothing(tmp_path, capsys, monkeypatch):
    env_config = envs.default_config("flat", "ball", "B")
    policy_dir = train.initial_policy(
        env_config,
        PPOConfig(policy_hidden_layers=(8,), value_hidden_layers=(8,)),
        tmp_path / "policy",
        observation_layout.size(env_config, 0),
    )
    (tmp_path / "not_a_policy").mkdir()
    (tmp_path / "a_file").write_text("x")
    (tmp_path / "a_folder").mkdir()
    (tmp_path / "no_checkpoint").mkdir()  # the configs without the parameters
    for name in ("footforge.json", "ppo_network_config.json"):
        shutil.copy(policy_dir / name, tmp_path / "no_checkpoint" / name)
    cases = [
        ([str(tmp_path / "missing")], "no such folder"),
        ([str(tmp_path / "not_a_policy")], "not a footforge policy"),
        ([str(tmp_path / "no_checkpoint")], "checkpoint cannot be read"),
        ([str(policy_dir), "--out", str(tmp_path / "no" / "such" / "p.onnx")], "does not exist"),
        ([str(policy_dir), "--out", str(tmp_path / "a_file" / "p.onnx")], "is not a folder"),
        ([str(policy_dir), "--out", str(tmp_path / "a_folder")], "is a folder"),
    ]
    before = sorted(p.name for p in tmp_path.rglob("*"))
    for argv, message in cases:
        code = main(["export", *argv])
        captured = capsys.readouterr()
        assert code == 2, (argv, captured)
        errors = [line for line in captured.err.splitlines() if line.startswith("footforge export: error: ")]
        assert len(errors) == 1 and message in errors[0], captured.err  # then the "fix:" line
        assert "Traceback" not in captured.err and "written" not in captured.out
    assert sorted(p.name for p in tmp_path.rglob("*")) == before

    # A write that fails midway (here: a full disk) leaves neither the file nor its temporary, and
    # an earlier export in its place untouched.
    monkeypatch.chdir(tmp_path)
    assert main(["export", str(policy_dir)]) == 0
    written = tmp_path / f"{tmp_path.name}.onnx"  # the default: named after the folder holding policy/
    earlier = written.read_bytes()

    def full_disk(model, path):
        with open(path, "wb") as f:
            f.write(b"partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(onnx, "save_model", full_disk)
    capsys.readouterr()
    assert main(["export", str(policy_dir)]) == 2
    assert "No space left on device" in capsys.readouterr().err
    assert written.read_bytes() == earlier
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name]
    assert main(["export", str(policy_dir), "--out", str(tmp_path / "new.onnx")]) == 2
    assert not (tmp_path / "new.onnx").exists() and not list(tmp_path.glob(".new*"))


def test_a_file_footforge_did_not_write_is_never_replaced(tmp_path, capsys):
    """--out naming a user's file (notes, or an ONNX model from elsewhere) is refused, exit 2, the
    file untouched; footforge's own export is replaced; --force replaces anything."""
    env_config = envs.default_config("flat", "ball", "B")
    policy_dir = train.initial_policy(
        env_config,
        PPOConfig(policy_hidden_layers=(8,), value_hidden_layers=(8,)),
        tmp_path / "policy",
        observation_layout.size(env_config, 0),
    )
    notes = tmp_path / "todo.txt"
    notes.write_text("my notes")
    foreign = tmp_path / "theirs.onnx"
    onnx.save_model(
        onnx.helper.make_model(onnx.helper.make_graph([], "g", [], []), producer_name="someone"), str(foreign)
    )
    foreign_bytes = foreign.read_bytes()
    assert main(["export", str(policy_dir), "--out", str(foreign)]) == 2
    err = capsys.readouterr().err
    assert "not an ONNX policy footforge wrote" in err and "--force" in err and "Traceback" not in err
    for flags in ([], ["--force"]):  # not an .onnx name: refused, whatever --force says
        assert main(["export", str(policy_dir), "--out", str(notes), *flags]) == 2
        assert "--out must end in .onnx" in capsys.readouterr().err
    assert notes.read_text() == "my notes" and foreign.read_bytes() == foreign_bytes
    ours = tmp_path / "ours.onnx"
    assert main(["export", str(policy_dir), "--out", str(ours)]) == 0
    assert main(["export", str(policy_dir), "--out", str(ours)]) == 0  # footforge's own: replaced
    assert main(["export", str(policy_dir), "--out", str(foreign), "--force"]) == 0
    assert onnx.load(str(foreign)).producer_name == "footforge"


def test_commands_take_a_run_folder_for_its_policy(tmp_path, capsys):
    """export, evaluate, evaluate-closed-chain and play accept a training run's folder and use its
    policy/; a run that has not written one yet is named as such (exit 2)."""
    run = tmp_path / "run"
    env_config = envs.default_config("flat", "ball", "B")
    train.initial_policy(
        env_config,
        PPOConfig(policy_hidden_layers=(8,), value_hidden_layers=(8,)),
        run / "policy",
        observation_layout.size(env_config, 0),
    )
    assert train.policy_folder(run) == run / "policy" and train.policy_folder(run / "policy") == run / "policy"
    assert main(["export", str(run), "--out", str(tmp_path / "p.onnx")]) == 0
    assert onnx.load(str(tmp_path / "p.onnx")).producer_name == "footforge"
    unfinished = tmp_path / "unfinished"
    train.prepare_run_dir(unfinished)
    (unfinished / "config.json").write_text("{}")
    for argv in (
        ["export", str(unfinished)],
        ["evaluate", "--policy", str(unfinished), "--out", str(tmp_path / "e")],
        ["evaluate-closed-chain", "--policy", str(unfinished), "--out", str(tmp_path / "c")],
    ):
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "is a training run without a policy or an intact checkpoint yet" in err, (argv, err)
    assert not (tmp_path / "e").exists() and not (tmp_path / "c").exists()
