"""The two physics engines (footforge.envs.engine): MJX and MuJoCo's C engine step the same model for
the same task code, so from the same states and actions they agree; the C engine's results do not
depend on its thread count; its contact and force sensors measure what physics says they must."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import jax
import jax.numpy as jp
import numpy as np
import pytest

from footforge import envs
from footforge.envs import engine
from footforge.envs.engine_mujoco import THREADS_ENV
from footforge.errors import InputError

REPO = Path(__file__).resolve().parents[1]
ROBOTS = 4
STEPS = 2
CONVERGED = dict(solver_iterations=50, solver_ls_iterations=50)
"""Both engines solve the contacts to convergence here: at the stance model's 8 Newton iterations
(AOF) a physics step now and then ends unconverged, and an unconverged solve depends on its warm
start and precision (measured 2026-11-28: one AOF robot in 4 had an ankle 0.18 rad apart after one
policy step between C at 8 and C at 16+ iterations, which agree with each other)."""
# How far the engines may part over STEPS policy steps (0.04 s) of random actions, float32 MJX against
# float64 C, both converged. Measured (flat AOF BH, 4 robots, 2026-11-28): the base, actuated joints,
# command and action observations within 2e-4; the passive foot joints, whose links weigh grams
# and swing freely between contacts, up to 0.12 (a joint velocity x 0.05); foot forces 30 N of
# ~130 N (a sole's contact points). The negative control (one physics step more per policy step)
# parts by 0.05-1 in the first group, so OBS_ATOL tells a real difference from rounding.
OBS_ATOL = 5e-3
PASSIVE_OBS_ATOL = 0.3
FORCE_ATOL_N = 60.0
ACTUATED_OBS = 48
"""The observation's first 48 entries: base velocities, gravity, command, the 12 joints' positions
and velocities, the last action (observation_layout); the passive foot joints follow."""


def _pair(built, task, feet, policy, **overrides):
    """(MJX env, C env) of one configuration, pushes off (a push is the same in both, but it would
    only add a large velocity step to compare)."""
    config = envs.default_config(task, feet, policy)
    kwargs = dict(build_dir=str(built[feet][0]), pushes=replace(config.pushes, enabled=False)) | overrides
    return envs.make(task, feet, policy, physics="mjx", **kwargs), envs.make(task, feet, policy, physics="mujoco",
                                                                            **kwargs)


def _rollout(env, actions):
    """A reset of ROBOTS robots (the same keys for every engine) and STEPS steps of `actions`:
    per step (obs, reward, done, foot contacts, foot forces, probe points, foot sites, base pose)."""
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(0), ROBOTS))

    def read(s):
        d = s.pipeline_state
        return {"obs": s.obs, "reward": s.reward, "done": s.done, "contacts": jax.vmap(env.foot_contacts)(d),
                "forces": jax.vmap(env.foot_forces)(d), "probes": jax.vmap(env.physics.probe_points)(d),
                "feet": jax.vmap(env.foot_positions)(d), "base_pose": d.qpos[:, :7]}
    rows = [read(state)]
    for a in actions:
        state = step(state, a)
        rows.append(read(state))
    return jax.tree.map(np.asarray, rows)


def _actions(env, seed=1):
    return 0.3 * jax.random.normal(jax.random.PRNGKey(seed), (STEPS, ROBOTS, env.action_size))


def _parts(mjx_rows, c_rows):
    """The largest difference of each quantity over every step and robot (the observation split
    into its actuated part and the passive foot joints)."""
    def split(row):
        return row | {"obs": row["obs"][:, :ACTUATED_OBS], "passive_obs": row["obs"][:, ACTUATED_OBS:]}
    pairs = [(split(m), split(c)) for m, c in zip(mjx_rows, c_rows)]
    return {k: max(float(np.max(np.abs(m[k].astype(float) - c[k].astype(float)), initial=0.0)) for m, c in pairs)
            for k in pairs[0][0]}


def _assert_agree(parts):
    assert parts["obs"] < OBS_ATOL, parts
    assert parts["passive_obs"] < PASSIVE_OBS_ATOL, parts
    assert parts["reward"] < 1e-3, parts
    assert parts["done"] == 0 and parts["contacts"] == 0, parts
    assert parts["forces"] < FORCE_ATOL_N, parts
    assert parts["probes"] < 1e-3 and parts["feet"] < 1e-3 and parts["base_pose"] < 1e-4, parts


def test_flat_aof_engines_agree_and_the_comparison_can_fail(built):
    """AOF with its passive joints observed (BH): observations, rewards, termination, each foot's
    contact and normal force, the base and thigh probe points and the touchdown sites agree between
    the engines over 0.1 s of random actions; a C engine taking one physics step more per policy
    step does not (the comparison is able to fail)."""
    mjx_env, c_env = _pair(built, "flat", "aof", "BH", **CONVERGED)
    actions = _actions(mjx_env)
    mjx_rows, c_rows = _rollout(mjx_env, actions), _rollout(c_env, actions)
    parts = _parts(mjx_rows, c_rows)
    _assert_agree(parts)
    assert np.all(c_rows[0]["contacts"]), "a robot at its stand pose has every foot down"
    longer = envs.make("flat", "aof", "BH", physics="mujoco", build_dir=str(built["aof"][0]), decimation=9,
                       pushes=replace(c_env.config.pushes, enabled=False), **CONVERGED)
    control = _parts(mjx_rows, _rollout(longer, actions))
    assert control["obs"] > 10 * OBS_ATOL, control


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("task,feet,policy", [("flat", "ball", "B"), ("rough", "ball", "P"), ("rough", "aof", "PH")])
def test_engines_agree(built, task, feet, policy):
    """As the AOF test, for ball feet and on the rough terrain (height scan, heightfield contacts,
    the curriculum's spawns)."""
    from test_rough import SMALL

    overrides = {"terrain": SMALL} if task == "rough" else {}
    mjx_env, c_env = _pair(built, task, feet, policy, **overrides, **CONVERGED)
    actions = _actions(mjx_env)
    _assert_agree(_parts(_rollout(mjx_env, actions), _rollout(c_env, actions)))


def test_c_engine_results_do_not_depend_on_its_threads(built, monkeypatch):
    """The same seed gives the same bytes with one thread and with two (each robot's warm start is
    its own, never a thread's leftover)."""
    rows = []
    for threads in ("1", "2"):
        monkeypatch.setenv(THREADS_ENV, threads)
        _, c_env = _pair(built, "flat", "aof", "B")
        assert c_env.physics._threads == int(threads)
        rows.append(_rollout(c_env, _actions(c_env, seed=3)))
    for one, two in zip(*rows):
        for k in one:
            assert np.array_equal(one[k], two[k]), k
    monkeypatch.setenv(THREADS_ENV, "0")
    with pytest.raises(InputError, match=THREADS_ENV):
        _pair(built, "flat", "aof", "B")


@pytest.mark.parametrize("feet", ["ball", "aof"])
def test_c_engine_feet_carry_the_robots_weight(built, feet):
    """Standing still (zero actions, 1 s), the four feet's normal forces from the contact sensors
    add up to the robot's weight, and the base's probes are above the ground; placed 5 cm into the
    ground, the base's probes end the episode."""
    _, env = _pair(built, "flat", feet, "B")
    step = jax.jit(env.step)
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    for _ in range(50):
        state = step(state, jp.zeros(env.action_size))
    weight_n = float(env.robot.model.body_subtreemass[0] * 9.81)
    forces = np.asarray(env.foot_forces(state.pipeline_state))
    assert abs(forces.sum() / weight_n - 1.0) < 0.02, (forces, weight_n)
    assert np.all(forces > 0.1 * weight_n), forces  # each foot carries its share
    assert float(state.done) == 0.0
    qpos = state.pipeline_state.qpos.at[2].set(0.05)  # the base box reaches below the floor
    sunk = env.physics.forward(env.mjx_model, env.physics.place(state.pipeline_state, qpos, state.pipeline_state.qvel,
                                                                 state.pipeline_state.ctrl))
    base, _ = env.contact_flags(sunk)
    assert bool(base)


def test_physics_choice_and_refusals(built):
    assert engine.resolve("auto") == ("mujoco" if jax.default_backend() == "cpu" else "mjx")
    assert engine.resolve("mjx") == "mjx"
    with pytest.raises(InputError, match="unknown physics"):
        engine.resolve("bullet")
    config = envs.default_config("flat", "aof", "B")
    with pytest.raises(InputError, match="randomisation is not yet supported"):
        envs.make("flat", "aof", "B", physics="mujoco", build_dir=str(built["aof"][0]),
                  randomization=replace(config.randomization, friction_range=(0.5, 1.0)))


def test_a_run_resumes_under_the_other_engine(tmp_path):
    """Checkpoints move between the engines: a run trained on MJX resumes on the C engine (only
    EnvConfig.physics differs), while any other difference is still refused."""
    from footforge.rl import train

    run = tmp_path / "rough_aof_P"
    shutil.copytree(REPO / "policies/rough_aof_P", run)
    saved = json.loads((run / "config.json").read_text())
    assert saved["env"].get("physics", "mjx") == "mjx"
    env_config, ppo = train.load_run_config(run)
    offset, restore, _, _ = train._resume_state(run, replace(env_config, physics="mujoco"), ppo, print, False)
    assert offset == json.loads((run / "progress.json").read_text())["global_step"] and restore is not None
    with pytest.raises(InputError, match="other settings"):
        train._resume_state(run, replace(env_config, physics="mujoco", decimation=4), ppo, print, False)
