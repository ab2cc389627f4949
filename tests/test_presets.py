"""Training presets and `--set` overrides (footforge/rl/presets.py): each preset resolves to a
configuration config.json can hold, overrides set one leaf as its field's type or are refused by
name, `footforge train` records its recipe and a resume compares the whole configuration, and every
shipped run is its recorded recipe."""

import json
from dataclasses import replace

import pytest

from footforge import envs
from footforge.errors import InputError
from footforge.rl import presets
from footforge.rl.config import PPOConfig, env_config_from_dict, from_dict, to_dict

from conftest import REPO


@pytest.mark.parametrize("task, name", [(t, n) for t in presets.PRESETS for n in presets.PRESETS[t]])
@pytest.mark.parametrize("feet", ["ball", "aof"])
def test_every_preset_resolves_to_a_configuration_config_json_holds(task, name, feet):
    env, ppo = presets.resolve(task, feet, "B", name)
    assert env_config_from_dict(json.loads(json.dumps(to_dict(env)))) == env
    assert from_dict(PPOConfig, json.loads(json.dumps(to_dict(ppo)))) == ppo
    ppo.check()
    # The physics step and solver iterations are the contact model's on these feet (envs.physics).
    physics = envs.physics(feet, env.contact_model)
    assert (env.sim_dt, env.decimation) == (physics["sim_dt"], physics["decimation"])
    assert env.sim_dt * env.decimation == pytest.approx(0.02)  # the paper's 50 Hz policy


def test_the_default_preset_is_the_task_s_defaults():
    from footforge.rl.config import default_ppo

    for task in presets.PRESETS:
        assert presets.resolve(task, "aof", "B") == (envs.default_config(task, "aof", "B"), default_ppo(task))


def test_the_cpu_preset_is_what_the_shipped_cpu_policies_trained_on():
    """The `cpu` preset is the recipe of the flat policies trained on this CPU: 128 robots x 24 steps,
    the `fast` contact, commands +-1 / +-0.5 m/s, no feet-air-time term, entropy 0.001."""
    env, ppo = presets.resolve("flat", "aof", "B", "cpu")
    assert (ppo.num_envs, ppo.unroll_length, ppo.batch_size, ppo.num_minibatches) == (128, 24, 64, 4)
    assert env.contact_model == "fast" and env.sim_dt == 0.005 and env.decimation == 4
    assert env.commands.lin_vel_x_range == (-1.0, 1.0) and env.commands.lin_vel_y_range == (-0.5, 0.5)
    assert env.rewards.feet_air_time.scale == 0.0 and ppo.entropy_cost == 0.001
    assert env.commands.resample_s == envs.FLAT_COMMAND_RESAMPLE_S


def test_cpu_robust_is_cpu_with_denser_pushes_and_commands():
    """`cpu-robust` (the second stage) changes only the push and command schedules of `cpu`: a push
    every 5 s and a new command every 2.5 s, three and seven per 20-s episode."""
    cpu_env, cpu_ppo = presets.resolve("flat", "aff", "B", "cpu")
    env, ppo = presets.resolve("flat", "aff", "B", "cpu-robust")
    assert ppo == cpu_ppo
    assert env.pushes.interval_s == 5.0 and env.commands.resample_s == 2.5
    assert env == replace(
        cpu_env, pushes=replace(cpu_env.pushes, interval_s=5.0), commands=replace(cpu_env.commands, resample_s=2.5)
    )
    assert env.episode_length_s / env.commands.resample_s - 1 == 7


@pytest.mark.parametrize(
    "override, read",
    [
        ("ppo.entropy_cost=0.003", lambda e, p: p.entropy_cost == 0.003),
        ("ppo.num_timesteps=2e6", lambda e, p: p.num_timesteps == 2_000_000 and isinstance(p.num_timesteps, int)),
        ("ppo.policy_hidden_layers=512,256,128", lambda e, p: p.policy_hidden_layers == (512, 256, 128)),
        ("ppo.policy_mean_clip=1.5", lambda e, p: p.policy_mean_clip == 1.5),
        ("env.commands.lin_vel_x_range=-0.5,1.5", lambda e, p: e.commands.lin_vel_x_range == (-0.5, 1.5)),
        ("env.rewards.feet_air_time.scale=0.25", lambda e, p: e.rewards.feet_air_time.scale == 0.25),
        ("env.rewards.lin_vel_xy.params.sigma=0.5", lambda e, p: e.rewards.lin_vel_xy.params == {"sigma": 0.5}),
        ("env.rewards.base_height.params.target_m=0.5", lambda e, p: e.rewards.base_height.params["target_m"] == 0.5),
        ("env.pushes.enabled=false", lambda e, p: e.pushes.enabled is False),
        ("env.randomization.friction_range=0.5,1.25", lambda e, p: e.randomization.friction_range == (0.5, 1.25)),
        ("env.action=velocity", lambda e, p: e.action == "velocity"),
    ],
)
def test_an_override_sets_one_leaf_as_its_field_s_type(override, read):
    base_env, base_ppo = presets.resolve("flat", "aof", "B", "cpu")
    env, ppo = presets.resolve("flat", "aof", "B", "cpu", [override])
    assert read(env, ppo)
    # Nothing else moved: config.json's forms differ in that one leaf.
    from footforge.rl.config import config_differences

    changed = config_differences(
        {"env": to_dict(base_env), "ppo": to_dict(base_ppo)}, {"env": to_dict(env), "ppo": to_dict(ppo)}
    )
    assert [c.split(":")[0] for c in changed] == [override.split("=")[0]]


def test_the_contact_model_override_brings_its_physics():
    env, _ = presets.resolve("flat", "aof", "B", "cpu", ["env.contact_model=stance"])
    default, _ = presets.resolve("flat", "aof", "B", "default")
    assert (env.contact_model, env.sim_dt, env.decimation, env.solver_iterations, env.solver_ls_iterations) == (
        default.contact_model,
        default.sim_dt,
        default.decimation,
        default.solver_iterations,
        default.solver_ls_iterations,
    )
    assert env.sim_dt < presets.resolve("flat", "aof", "B", "cpu")[0].sim_dt


@pytest.mark.parametrize(
    "override, words",
    [
        ("ppo.entropy=0.1", "did you mean entropy_cost"),
        ("env.commands.resample_s=often", "'often' is not a number"),
        ("ppo.num_envs=1.5", "not a whole number"),
        ("env.commands=3", "'commands' is a section"),
        ("env.commands.resample_s.x=3", "'resample_s' is a value"),
        ("env.rewards.lin_vel_xy.params.sigmaa=0.5", "did you mean sigma"),
        ("env.rewards.lin_vel_xy.params.sigma=wide", "'wide' is not a number"),
        ("env.feet=ball", "fix: --feet"),
        ("env.physics=mjx", "fix: --physics"),
        ("env.action=run", "one of velocity, position"),
        ("env.pushes.enabled=maybe", "true or false"),
        ("env.commands.lin_vel_x_range=1", "2 comma-separated numbers"),
        ("ppo.num_envs=none", "cannot be none"),
        ("entropy_cost=0.1", "SECTION.FIELD=VALUE"),
        ("ppo.entropy_cost", "SECTION.FIELD=VALUE"),
    ],
)
def test_a_bad_override_is_an_input_error_that_names_it(override, words):
    with pytest.raises(InputError) as e:
        presets.resolve("flat", "aof", "B", "cpu", [override])
    assert words in str(e.value) and override.split("=")[0].split(".")[0] in str(e.value)


def test_an_unknown_preset_lists_the_task_s():
    with pytest.raises(InputError, match="use one of default, cpu"):
        presets.resolve("rough", "aof", "P", "forward")


@pytest.mark.parametrize("preset_name", ["default", "cpu", "paper"])
def test_overrides_between_give_the_configuration_back(preset_name):
    """A configuration made from one preset is reached from another by the overrides derived
    between them (the contact model's physics included)."""
    env, ppo = presets.resolve(
        "flat", "aff", "B", "forward", ["env.float64_physics=true", "ppo.seed=3", "env.rewards.base_height.scale=-5"]
    )
    overrides = presets.overrides_between(env, ppo, preset_name)
    assert presets.resolve("flat", "aff", "B", preset_name, overrides) == (env, ppo)
    assert ("ppo.seed=3" in overrides) and not any(o.startswith("env.feet") for o in overrides)


SHIPPED = sorted((REPO / "policies").glob("*/config.json"))


@pytest.mark.parametrize("config_file", SHIPPED, ids=[p.parent.name for p in SHIPPED])
def test_each_shipped_run_is_its_recorded_recipe(config_file):
    """config.json = its recorded preset + overrides (the run-time engine and build aside), and the
    policy card lists the same recipe."""
    saved = json.loads(config_file.read_text())
    env, ppo = env_config_from_dict(saved["env"]), from_dict(PPOConfig, saved["ppo"])
    recipe = presets.recipe_of(saved)
    assert recipe is not None, f"{config_file}: no recipe"
    got_env, got_ppo = presets.resolve(env.task, env.feet, env.policy, recipe[0], recipe[1])
    assert replace(got_env, physics=env.physics, build_dir=env.build_dir) == env and got_ppo == ppo
    card = config_file.parent / "evaluation" / "policy_card.md"
    if (config_file.parent / "policy").is_dir():
        text = card.read_text()
        assert f"preset `{recipe[0]}`" in text and all(f"`{o}`" in text for o in recipe[1])


# --- footforge train --preset/--set ---


def _capture_train(monkeypatch):
    """footforge train's call of rl.train.train recorded instead of made (test_train's helper)."""
    from test_train import _capture_train as capture

    return capture(monkeypatch)


def test_train_resolves_preset_flags_and_sets_in_order_and_records_them(built, tmp_path, monkeypatch, capsys):
    from footforge.cli.train import main

    seen = _capture_train(monkeypatch)
    root = ["--feet", "ball", "--build-root", str(built["ball"][0].parent)]
    assert (
        main(
            "flat",
            "",
            [
                *root,
                "--out",
                str(tmp_path / "a"),
                "--preset",
                "cpu",
                "--num-envs",
                "16",
                "--batch-size",
                "8",
                "--set",
                "ppo.entropy_cost=0.01",
                "--set",
                "env.commands.resample_s=10",
            ],
            prog="footforge train flat",
        )
        == 0
    )
    recipe = seen["kwargs"]["recipe"]
    assert recipe == {
        "preset": "cpu",
        "overrides": [
            "ppo.num_envs=16",
            "ppo.batch_size=8",
            "ppo.entropy_cost=0.01",
            "env.commands.resample_s=10",
            "ppo.num_eval_envs=16",
        ],
    }
    env, ppo = presets.resolve("flat", "ball", "B", "cpu", recipe["overrides"])
    assert seen["ppo"] == ppo and replace(seen["env"], physics=env.physics, build_dir=None) == env
    assert ppo.entropy_cost == 0.01 and env.commands.resample_s == 10 and env.contact_model == "fast"
    assert "preset cpu, overrides ppo.num_envs=16" in capsys.readouterr().out
    # A --set after a flag wins: the order is the preset, the flags, then --set.
    assert (
        main("flat", "", [*root, "--out", str(tmp_path / "b"), "--preset", "cpu", "--seed", "1", "--set", "ppo.seed=2"])
        == 0
    )
    assert seen["ppo"].seed == 2


def test_a_second_stage_preset_from_scratch_is_noted_not_refused(built, tmp_path, monkeypatch, capsys):
    """`cpu-robust` goes on from a `cpu` policy (--init-from); started from scratch, footforge train says so
    and trains (what it asked for); a first-stage preset says nothing of the kind."""
    from footforge.cli.train import main

    seen = _capture_train(monkeypatch)
    root = ["--feet", "ball", "--build-root", str(built["ball"][0].parent), "--num-envs", "16", "--batch-size", "8"]
    assert main("flat", "", [*root, "--out", str(tmp_path / "a"), "--preset", "cpu-robust"]) == 0
    out = capsys.readouterr().out
    assert "--preset cpu-robust is a second stage" in out and "--preset cpu (--init-from RUN)" in out
    assert seen["kwargs"]["recipe"]["preset"] == "cpu-robust"
    assert main("flat", "", [*root, "--out", str(tmp_path / "b"), "--preset", "cpu"]) == 0
    assert "second stage" not in capsys.readouterr().out


def test_a_bad_set_is_refused_before_anything_is_announced(built, tmp_path, monkeypatch, capsys):
    from footforge.cli.train import main

    seen = _capture_train(monkeypatch)
    assert (
        main(
            "flat",
            "",
            ["--feet", "ball", "--out", str(tmp_path / "a"), "--set", "ppo.entropy=0.1"],
            prog="footforge train flat",
        )
        == 2
    )
    out, err = capsys.readouterr()
    assert "footforge train flat: error: --set ppo.entropy=0.1" in err and "entropy_cost" in err
    assert "robots on" not in out and not seen and not (tmp_path / "a").exists()


def test_a_resume_with_another_recipe_names_the_differences(built, tmp_path, monkeypatch, capsys):
    from footforge.cli.train import main
    from footforge.rl import train

    cfg, ppo = presets.resolve(
        "flat", "ball", "B", "cpu", ["ppo.num_envs=8", "ppo.batch_size=8", "ppo.num_minibatches=1"]
    )
    run = train.prepare_run_dir(tmp_path / "run")
    (run / "config.json").write_text(
        json.dumps({"env": to_dict(replace(cfg, build_dir=str(built["ball"][0]))), "ppo": to_dict(ppo)})
    )
    seen = _capture_train(monkeypatch)
    assert main("flat", "", ["--out", str(run), "--resume", "--preset", "default"]) == 2
    err = capsys.readouterr().err
    assert "not the run's configuration" in err and "ppo.num_envs: 8 in the run, 2048 now" in err
    assert (
        main(
            "flat",
            "",
            [
                "--out",
                str(run),
                "--resume",
                "--preset",
                "cpu",
                "--set",
                "ppo.num_envs=8",
                "--set",
                "ppo.batch_size=8",
                "--set",
                "ppo.num_minibatches=1",
                "--set",
                "ppo.entropy_cost=0.01",
            ],
        )
        == 2
    )
    assert "ppo.entropy_cost: 0.001 in the run, 0.01 now" in capsys.readouterr().err
    assert (
        main(
            "flat",
            "",
            [
                "--out",
                str(run),
                "--resume",
                "--preset",
                "cpu",
                "--set",
                "ppo.num_envs=8",
                "--set",
                "ppo.batch_size=8",
                "--set",
                "ppo.num_minibatches=1",
            ],
        )
        == 0
    )
    assert seen["ppo"] == ppo


def test_the_learning_benchmark_s_recorded_commands_resolve_to_the_shipped_configurations():
    """benchmarks/learning_cpu.py is presets + overrides: the variant that trained the earlier ball policy's
    last stage (`--preset full --variant today+fast+airtime=0+resample=10+entropy=0.001`, 258,048 steps per
    checkpoint) is the `cpu` preset with commands every 10 s; the command that trained flat_aof_B's first 10 M
    steps gives that preset exactly (its later stages are `cpu-robust`'s); flat_ball_B_cpu, trained by
    `footforge train --preset cpu` from scratch, is it too (to 20 M), and flat_aff_B went on from it through
    `cpu-robust`."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("learning_cpu", REPO / "benchmarks/learning_cpu.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)

    def shipped(name):
        saved = json.loads((REPO / "policies" / name / "config.json").read_text())
        env = env_config_from_dict(saved["env"])
        return replace(env, physics="mjx", build_dir=None), from_dict(PPOConfig, saved["ppo"])

    env, ppo, recipe = module.configure(
        "ball",
        "full",
        "today+fast+airtime=0+resample=10+entropy=0.001",
        ["ppo.num_timesteps=3870720", "ppo.checkpoint_every_steps=258048"],
    )
    cpu_every_10_s = ["env.commands.resample_s=10", "ppo.num_timesteps=3870720"]
    assert (env, ppo) == presets.resolve("flat", "ball", "B", "cpu", cpu_every_10_s)
    assert presets.resolve("flat", "ball", "B", recipe["preset"], recipe["overrides"]) == (env, ppo)
    assert module.configure("ball", "cpu", "resample=10", ["ppo.num_timesteps=3870720"])[:2] == (env, ppo)
    # flat_aff_B went on from that preset's 10 M steps through the `cpu-robust` stage.
    assert shipped("flat_aff_B") == presets.resolve("flat", "aff", "B", "cpu-robust")
    # flat_ball_B_cpu is the preset from scratch resumed to 20 M steps: its recipe records the new total.
    assert shipped("flat_ball_B_cpu") == presets.resolve("flat", "ball", "B", "cpu", ["ppo.num_timesteps=20000000"])
    env, ppo, _ = module.configure(
        "aof",
        "full",
        "today+fast+airtime=0+entropy=0.001",
        ["ppo.num_timesteps=10000000", "ppo.checkpoint_every_steps=258048"],
    )
    assert (env, ppo) == presets.resolve("flat", "aof", "B", "cpu")
    # flat_aof_B is that run resumed to 20 M steps: its recipe records the new total.
    # flat_aof_B went on from that preset's 20.13 M steps with a push every 5 s (10 M steps), then 5 M steps of
    # the `cpu-robust` stage.
    assert shipped("flat_aof_B") == presets.resolve("flat", "aof", "B", "cpu-robust", ["ppo.num_timesteps=5000000"])


@pytest.mark.parametrize(
    "override, read",
    [
        ("env.observations.base_lin_vel.noise=0.2", lambda e, p: e.observations.base_lin_vel.noise == 0.2),
        ("env.observations.command.scale=1,1,0.5", lambda e, p: e.observations.command.scale == (1.0, 1.0, 0.5)),
        ("ppo.seed=12345678901234567891", lambda e, p: p.seed == 12345678901234567891),
    ],
)
def test_observation_groups_and_exact_integers_are_overridden(override, read):
    """An observation group's scale and noise (fields typed for type checkers only) take overrides, and
    a whole number is read exactly, not through a float."""
    assert read(*presets.resolve("flat", "aof", "B", "cpu", [override]))


@pytest.mark.parametrize(
    "override, words",
    [
        ("ppo.learning_rate=nan", "finite"),
        ("env.terrain.seed=3", "rough task's"),
        ("env.curriculum.initial_max_level=2", "rough task's"),
    ],
)
def test_overrides_that_would_do_nothing_or_poison_training_are_refused(override, words):
    with pytest.raises(InputError, match=words):
        presets.resolve("flat", "aof", "B", "cpu", [override])
    if "terrain" in override:  # the rough task takes it
        assert presets.resolve("rough", "aof", "P", "cpu", [override])[0].terrain.seed == 3


def test_a_resume_with_set_alone_compares_with_the_run_s_own_preset(built, tmp_path, monkeypatch, capsys):
    """--set without --preset on --resume is read over the run's recorded preset (not the default), and
    the total is --timesteps' to change (a --set of it is refused: it would be ignored)."""
    from footforge.cli.train import main
    from footforge.rl import train

    cfg, ppo = presets.resolve(
        "flat", "ball", "B", "cpu", ["ppo.num_envs=8", "ppo.batch_size=8", "ppo.num_minibatches=1"]
    )
    run = train.prepare_run_dir(tmp_path / "run")
    (run / "config.json").write_text(
        json.dumps(
            {
                "env": to_dict(replace(cfg, build_dir=str(built["ball"][0]))),
                "ppo": to_dict(ppo),
                "recipe": {
                    "preset": "cpu",
                    "overrides": ["ppo.num_envs=8", "ppo.batch_size=8", "ppo.num_minibatches=1"],
                },
            }
        )
    )
    seen = _capture_train(monkeypatch)
    assert (
        main(
            "flat",
            "",
            [
                "--out",
                str(run),
                "--resume",
                "--set",
                "ppo.num_envs=8",
                "--set",
                "ppo.batch_size=8",
                "--set",
                "ppo.num_minibatches=1",
            ],
        )
        == 0
    )
    assert seen["ppo"] == ppo
    assert main("flat", "", ["--out", str(run), "--resume", "--set", "ppo.num_timesteps=20000000"]) == 2
    assert "with --timesteps" in capsys.readouterr().err


def test_a_resume_that_extends_the_run_records_the_new_total_in_its_recipe(built, tmp_path, monkeypatch):
    """After --resume --timesteps N the recorded recipe still resolves to config.json."""
    from footforge.rl import train

    cfg, ppo = presets.resolve(
        "flat",
        "ball",
        "B",
        "cpu",
        ["ppo.num_envs=8", "ppo.batch_size=8", "ppo.num_minibatches=1", "ppo.checkpoint_every_steps=32"],
    )
    recipe = {
        "preset": "cpu",
        "overrides": ["ppo.num_envs=8", "ppo.batch_size=8", "ppo.num_minibatches=1", "ppo.checkpoint_every_steps=32"],
    }
    cfg = replace(cfg, build_dir=str(built["ball"][0]))
    monkeypatch.setattr(train, "_resume_state", lambda *a: (64, None, 0, 0.0))
    monkeypatch.setattr(train, "_run_ppo", lambda *a, **k: {})
    run = train.prepare_run_dir(tmp_path / "run")
    (run / "config.json").write_text(json.dumps({"env": to_dict(cfg), "ppo": to_dict(ppo), "recipe": recipe}))
    longer = replace(ppo, num_timesteps=ppo.num_timesteps * 2)
    train.train(cfg, longer, run, resume=True, notice=lambda text: None)
    saved = json.loads((run / "config.json").read_text())
    name, overrides = presets.recipe_of(saved)
    assert presets.resolve("flat", "ball", "B", name, overrides)[1] == longer
    assert overrides[-1] == f"ppo.num_timesteps={longer.num_timesteps}"
