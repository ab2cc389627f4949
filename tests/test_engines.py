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
TIGHT = 1e-6
"""MJX in float64 against the C engine (float64 always): the same physics to rounding. Measured
(flat ball B, 4 robots x 2 policy steps of random actions, 2026-11-28): base pose and foot sites
3e-15 m, foot forces 8e-11 N, observations and rewards bit-equal (float32)."""
# Float32 MJX against float64 C (the slow tests), both converged: float32 rounding grows with the
# legs' motion. Measured (4 robots x 2 steps, 2026-11-28): flat ball, actions 0.3 N(0, 1), observations
# 0.019, feet 3.3 mm, base 0.15 mm, forces 15 N (zero actions: all within 2e-5); AOF, the base,
# actuated joints, command and action within 0.12, the passive foot joints (links of grams swinging
# freely between contacts) 0.12, forces 30 N of ~130 N.
OBS_ATOL = 0.05
PASSIVE_OBS_ATOL = 0.3
FORCE_ATOL_N = 60.0
POSITION_ATOL_M = 0.01
ACTUATED_OBS = 48
"""The observation's first 48 entries: base velocities, gravity, command, the 12 joints' positions
and velocities, the last action (observation_layout); the passive foot joints follow."""


def _pair(built, task, feet, policy, **overrides):
    """(MJX env, C env) of one configuration, pushes off (a push is the same in both, but it would
    only add a large velocity step to compare)."""
    config = envs.default_config(task, feet, policy)
    kwargs = dict(build_dir=str(built[feet][0]), pushes=replace(config.pushes, enabled=False)) | overrides
    return envs.make(task, feet, policy, physics="mjx", **kwargs), envs.make(
        task, feet, policy, physics="mujoco", **kwargs
    )


_COMPILED: dict = {}


def _compiled(env):
    """env's batched reset and step, jitted once per env (a test rolling one env out twice compiles once)."""
    if id(env) not in _COMPILED:
        _COMPILED[id(env)] = (
            env,
            jax.jit(jax.vmap(env.reset)),
            jax.jit(jax.vmap(env.step)),
        )  # env kept: its id stays its own
    return _COMPILED[id(env)][1:]


def _rollout(env, actions):
    """A reset of ROBOTS robots (the same keys for every engine) and STEPS steps of `actions`:
    per step (obs, reward, done, foot contacts, foot forces, probe points, foot sites, base pose)."""
    reset, step = _compiled(env)
    state = reset(jax.random.split(jax.random.PRNGKey(0), ROBOTS))

    def read(s):
        d = s.pipeline_state
        return {
            "obs": s.obs,
            "reward": s.reward,
            "done": s.done,
            "contacts": jax.vmap(env.foot_contacts)(d),
            "forces": jax.vmap(env.foot_forces)(d),
            "probes": jax.vmap(env.physics.probe_points)(d),
            "feet": jax.vmap(env.foot_positions)(d),
            "base_pose": d.qpos[:, :7],
        }

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
    return {
        k: max(float(np.max(np.abs(m[k].astype(float) - c[k].astype(float)), initial=0.0)) for m, c in pairs)
        for k in pairs[0][0]
    }


def _assert_agree(parts, obs=OBS_ATOL, passive=PASSIVE_OBS_ATOL, force_n=FORCE_ATOL_N, position_m=POSITION_ATOL_M):
    assert parts["obs"] <= obs and parts["passive_obs"] <= passive, parts
    assert parts["reward"] <= max(obs / 50, 1e-7), parts
    assert parts["done"] == 0 and parts["contacts"] == 0, parts
    assert parts["forces"] <= force_n, parts
    assert max(parts["probes"], parts["feet"], parts["base_pose"]) <= position_m, parts


_FLOAT64_PARITY = """
import json, sys
sys.path.insert(0, sys.argv[1])
import test_engines as T
feet, policy = sys.argv[2], sys.argv[3]
built = {feet: (sys.argv[4], None)}
mjx_env, c_env = T._pair(built, "flat", feet, policy, float64_physics=True, **T.CONVERGED)
_, longer = T._pair(built, "flat", feet, policy, float64_physics=True, decimation=9, **T.CONVERGED)
actions = T._actions(mjx_env)
rows = T._rollout(mjx_env, actions)
print(json.dumps({"same": T._parts(rows, T._rollout(c_env, actions)),
                  "one_more_step": T._parts(rows, T._rollout(longer, actions))}))
"""


@pytest.fixture(scope="module")
def float64_parts(built) -> dict:
    """_parts of MJX in float64 against the C engine, and against a C engine taking one physics step
    more per policy step, for flat ball B, in a subprocess (JAX's x64 is process-wide)."""
    import os
    import subprocess
    import sys

    env = os.environ | {"JAX_ENABLE_X64": "1"}
    done = subprocess.run(
        [sys.executable, "-c", _FLOAT64_PARITY, str(Path(__file__).parent), "ball", "B", str(built["ball"][0])],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # MJX compiled in float64 in a subprocess: 1-2 minutes on 2 cores
@pytest.mark.timeout(900)  # explicit budget: several times its time on 2 quiet cores
def test_engines_are_the_same_physics_in_float64(float64_parts):
    """MJX in float64 and the C engine (float64) step flat ball robots under random actions to the
    same states, contacts, forces, probes and observations, to rounding (TIGHT)."""
    parts = float64_parts["same"]
    _assert_agree(parts, obs=TIGHT, passive=TIGHT, force_n=TIGHT, position_m=TIGHT)


@pytest.mark.slow  # shares the subprocess above
@pytest.mark.timeout(900)
def test_the_engine_comparison_can_fail(float64_parts):
    """The same comparison against a C engine taking one physics step more per policy step (2.5 ms
    in 20) parts by thousands of times TIGHT (measured: base 3.6 mm, feet 8 mm, a foot's contact):
    the float64 comparison tells a real difference from rounding. (The float32 bounds of the slow
    tests are looser than this difference: there float32's own drift sets them.)"""
    parts = float64_parts["one_more_step"]
    assert parts["obs"] > 1e3 * TIGHT and parts["base_pose"] > 1e3 * TIGHT and parts["feet"] > 1e3 * TIGHT, parts


ROUGH_TILES = dict(
    num_levels=2, num_columns=2, tile_size_m=4.0, border_m=2.0, platform_m=1.0, proportions=(1, 1, 0, 0, 0, 0)
)
"""Four tiles (smooth and rough slopes, difficulty 0 and 0.5): the smallest terrain with slopes
under the feet, so that MJX compiles in a minute."""

_FLOAT64_AOF = """
import json, sys
sys.path.insert(0, sys.argv[1])
import test_engines as T
built = {"aof": (sys.argv[2], None)}
mjx_env, c_env = T._pair(built, "flat", "aof", "BH", float64_physics=True, **T.CONVERGED)
actions = T._actions(mjx_env)
print(json.dumps(T._parts(T._rollout(mjx_env, actions), T._rollout(c_env, actions))))
"""


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_engines_are_the_same_physics_in_float64_on_adaptive_feet(built):
    """As the flat ball comparison above, for the adaptive feet (AOF's split sole boxes and its
    passive joints, haptic observations) on flat ground: to rounding (TIGHT). In a subprocess
    (JAX's x64 is process-wide)."""
    import os
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-c", _FLOAT64_AOF, str(Path(__file__).parent), str(built["aof"][0])],
        capture_output=True,
        text=True,
        env=os.environ | {"JAX_ENABLE_X64": "1"},
        timeout=800,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    parts = json.loads(done.stdout.strip().splitlines()[-1])
    _assert_agree(parts, obs=TIGHT, passive=TIGHT, force_n=TIGHT, position_m=TIGHT)


_FLOAT64_ROUGH = """
import json, sys
sys.path.insert(0, sys.argv[1])
import test_engines as T
from footforge.envs.terrain import TerrainConfig
feet, policy = sys.argv[2], sys.argv[3]
built = {feet: (sys.argv[4], None)}
kw = dict(float64_physics=True, terrain=TerrainConfig(**T.ROUGH_TILES), **T.CONVERGED)
mjx_env, c_env = T._pair(built, "rough", feet, policy, **kw)
_, longer = T._pair(built, "rough", feet, policy, decimation=9, **kw)
actions = T._actions(mjx_env)
c_rows = T._rollout(c_env, actions)
out = {"same": T._parts(T._rollout(mjx_env, actions), c_rows),
       "one_more_step": T._parts(c_rows, T._rollout(longer, actions))}
if feet != "ball":  # the sole boxes the spheres stand in for: what the engines do with them
    boxes_mjx, boxes_c = T._pair(built, "rough", feet, policy, heightfield_soles="box", **kw)
    out["boxes"] = T._parts(T._rollout(boxes_mjx, actions), T._rollout(boxes_c, actions))
print(json.dumps(out))
"""


@pytest.mark.slow
@pytest.mark.timeout(1200)
@pytest.mark.parametrize("feet,policy", [("ball", "P"), ("aof", "PH")])
def test_engines_agree_on_a_heightfield(built, feet, policy):
    """Rough ball P (the height scan observed) and rough AOF PH (sole spheres, passive joints,
    haptic observations) on ROUGH_TILES (feet on slopes), float64, both solvers converged: the two
    engines' robots agree within float32's tolerances (OBS_ATOL, PASSIVE_OBS_ATOL; base and feet
    within 0.1 mm), far closer than the C engine's own robots to a C engine taking one physics step
    more per policy step (the control, computed here), with the same foot contacts.

    Each engine collides a heightfield with its own code, one test per terrain prism. For spheres
    (the ball, and the adaptive soles on heightfields: EnvConfig.heightfield_soles) they agree;
    for the build's sole boxes they do not (MuJoCo's C engine: one contact per prism, often through
    a prism's side face; MJX: a four-point manifold), which this test also computes, as the case it
    would fail. Measured 2026-11-28 (4 robots, 2 policy steps, action seeds 1-3): AOF PH with
    spheres, feet 0.3-3.7 um apart, base up to 0.24 um, observations up to 2.7e-4, foot forces up to
    0.9 N, the same contacts (control: feet 15-18 mm, base 1.9-2.7 mm, observations 0.48-0.87); with
    boxes feet 2.3-6.3 mm, base 0.2-1.35 mm, forces up to 700 N. Rough ball P: to 1e-5 at three
    robots; the fourth lands on a platform's edge (C: a second contact on the slope's prism, normal
    tilted 27 deg; MJX: one), feet 1.3 mm apart (control 11-13 mm), observations 0.025."""
    import os
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-c", _FLOAT64_ROUGH, str(Path(__file__).parent), feet, policy, str(built[feet][0])],
        capture_output=True,
        text=True,
        env=os.environ | {"JAX_ENABLE_X64": "1"},
        timeout=1100,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    same, control = out["same"], out["one_more_step"]
    assert same["done"] == 0 and same["contacts"] == 0, same
    assert same["obs"] <= OBS_ATOL and same["passive_obs"] <= PASSIVE_OBS_ATOL, same
    # The ball's robot on a platform edge (above) parts by a millimetre: half the control (its probes
    # 1.04 mm against 6.7, 2026-11-28); the adaptive feet's spheres agree to micrometres.
    closer = 2 if feet == "ball" else 10
    for key in ("base_pose", "feet", "probes"):
        assert same[key] < control[key] / closer, (key, same, control)
    if feet == "ball":
        assert max(same["feet"], same["base_pose"]) < 0.002, same
        return
    assert max(same["feet"], same["base_pose"], same["probes"]) < 1e-4 and same["forces"] < FORCE_ATOL_N, same
    # The test can fail: the same comparison with the build's sole boxes parts by millimetres.
    assert out["boxes"]["feet"] > 1e-3, out["boxes"]


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("task,feet,policy", [("flat", "ball", "B"), ("flat", "aof", "BH")])
def test_engines_agree_in_float32(built, task, feet, policy):
    """MJX in float32 (the default) against the C engine: the same within float32's rounding, grown
    over 2 policy steps of random actions (the bounds above), for ball and adaptive feet with their
    passive joints observed. Not on the rough terrain: there float32 MJX keeps a heightfield contact
    only while a foot penetrates, its depth in 0.12 um steps (docs/training.md), and within 2 steps
    a foot's contact differed and the feet parted by 19 mm (2026-11-27, ball P and AOF PH); the
    rough terrain's comparison is in float64 (the test above)."""
    mjx_env, c_env = _pair(built, task, feet, policy, **CONVERGED)
    actions = _actions(mjx_env)
    mjx_rows, c_rows = _rollout(mjx_env, actions), _rollout(c_env, actions)
    _assert_agree(_parts(mjx_rows, c_rows))
    assert np.all(c_rows[0]["contacts"]), "a robot at its start has every foot down"


@pytest.mark.slow  # about 24 s of the default run; the byte-for-byte evaluation (slow) repeats a whole rollout too
def test_c_engine_results_do_not_depend_on_its_threads(built, monkeypatch):
    """The same seed gives the same bytes with one thread and with two (each robot's warm start is
    its own, never a thread's leftover)."""
    from footforge.envs.engine_mujoco import Rollouts

    monkeypatch.setenv(THREADS_ENV, "1")
    _, c_env = _pair(built, "flat", "aof", "B")
    rows = []
    for threads in ("1", "2"):
        # A new pool of `threads` threads (what a C engine made under this setting holds); the
        # compiled step, which calls the pool from its host callback, stays the same program.
        monkeypatch.setenv(THREADS_ENV, threads)
        c_env.physics._rollouts = Rollouts(c_env.physics.model)
        assert c_env.physics._rollouts.threads == int(threads)
        rows.append(_rollout(c_env, _actions(c_env, seed=3)))
    for one, two in zip(*rows):
        for k in one:
            assert np.array_equal(one[k], two[k]), k
    monkeypatch.setenv(THREADS_ENV, "0")
    with pytest.raises(InputError, match=THREADS_ENV):
        _pair(built, "flat", "aof", "B")


@pytest.fixture(scope="module")
def c_envs(built):
    """feet -> (flat B env under the C engine, its jitted reset, its jitted step), each made and
    compiled once for the tests that share it."""
    made = {}

    def get(feet):
        if feet not in made:
            _, env = _pair(built, "flat", feet, "B")
            made[feet] = (env, jax.jit(env.reset), jax.jit(env.step))
        return made[feet]

    return get


@pytest.mark.parametrize("feet", ["ball", "aof"])
def test_c_engine_feet_carry_the_robots_weight(c_envs, feet):
    """Standing still (zero actions, 1 s), the four feet's normal forces from the contact sensors
    add up to the robot's weight, and the base's probes are above the ground; placed 5 cm into the
    ground, the base's probes end the episode."""
    env, reset, step = c_envs(feet)
    state = reset(jax.random.PRNGKey(0))
    for _ in range(50):
        state = step(state, jp.zeros(env.action_size))
    weight_n = float(env.robot.model.body_subtreemass[0] * 9.81)
    forces = np.asarray(env.foot_forces(state.pipeline_state))
    assert abs(forces.sum() / weight_n - 1.0) < 0.02, (forces, weight_n)
    assert np.all(forces > 0.1 * weight_n), forces  # each foot carries its share
    assert float(state.done) == 0.0
    qpos = state.pipeline_state.qpos.at[2].set(0.05)  # the base box reaches below the floor
    sunk = env.physics.forward(
        env.mjx_model,
        env.physics.place(state.pipeline_state, qpos, state.pipeline_state.qvel, state.pipeline_state.ctrl),
    )
    base, _ = env.contact_flags(sunk)
    assert bool(base)


def test_physics_choice_and_refusals(built):
    assert engine.resolve("auto") == ("mujoco" if jax.default_backend() == "cpu" else "mjx")
    assert engine.resolve("mjx") == "mjx"
    with pytest.raises(InputError, match="unknown physics"):
        engine.resolve("bullet")
    with pytest.raises(InputError, match="unknown physics"):
        envs.make("flat", "ball", "B", physics="bullet", build_dir=str(built["ball"][0]))


@pytest.mark.parametrize("command", ["train", "evaluate", "evaluate-closed-chain", "play"])
def test_a_bad_thread_count_is_refused_before_any_work(command, tmp_path, capsys, monkeypatch):
    """FOOTFORGE_PHYSICS_THREADS that is not a positive whole number: `footforge train` and
    `footforge evaluate` on the C engine, and the commands that always step it (the closed-chain
    evaluation, play), exit 2 naming the variable, and write nothing."""
    out = tmp_path / "out"
    monkeypatch.setenv(THREADS_ENV, "two")
    policy = str(REPO / "policies/flat_ball_B_cpu")
    if command == "train":
        from footforge.cli.train import main

        code = main("flat", "", ["--feet", "ball", "--out", str(out), "--physics", "mujoco", "--timesteps", "1000"])
    elif command == "evaluate":
        from footforge.cli.evaluate import main

        code = main(["--policy", policy, "--out", str(out), "--physics", "mujoco"])
    elif command == "evaluate-closed-chain":
        from footforge.cli.evaluate_closed_chain import main

        code = main(["--policy", policy, "--out", str(out)])
    else:
        from footforge.cli.play import main

        out = tmp_path / "out.json"
        code = main([policy, "--headless", "--log", str(out)])
    assert code == 2 and THREADS_ENV in capsys.readouterr().err
    assert not out.exists()


def test_a_run_resumes_under_the_other_engine(tmp_path):
    """Checkpoints move between the engines: a run resumes under the other engine than the one its
    config.json names (rough_aof_P, trained on this CPU under the C engine, resumed as a GPU would, in MJX;
    only EnvConfig.physics differs), while any other difference is still refused."""
    from footforge.rl import train

    run = tmp_path / "rough_aof_P"
    shutil.copytree(REPO / "policies/rough_aof_P", run)
    saved = json.loads((run / "config.json").read_text())
    other = "mjx" if saved["env"].get("physics", "mjx") == "mujoco" else "mujoco"
    env_config, ppo = train.load_run_config(run)
    offset, restore, _, _ = train._resume_state(run, replace(env_config, physics=other), ppo, print, False)
    assert offset == json.loads((run / "progress.json").read_text())["global_step"] and restore is not None
    with pytest.raises(InputError, match="other settings"):
        train._resume_state(
            run, replace(env_config, physics=other, decimation=2 * env_config.decimation), ppo, print, False
        )


def test_a_blown_up_c_simulation_ends_as_diverged(c_envs):
    """MuJoCo resets a simulation that blows up (here a base moving at 1e11 m/s) and carries on;
    the C engine reports it as MJX would, non-finite, so the episode ends as diverged."""
    env, reset, step = c_envs("ball")
    state = reset(jax.random.PRNGKey(0))
    d = state.pipeline_state
    state = state.replace(pipeline_state=env.physics.place(d, d.qpos, d.qvel.at[0].set(1e11), d.ctrl))
    after = step(state, jp.zeros(env.action_size))
    assert float(after.metrics["diverged"]) == 1.0 and float(after.done) == 1.0
    assert np.all(np.isfinite(np.asarray(after.pipeline_state.qpos)))  # restarted
    calm = step(after, jp.zeros(env.action_size))
    assert float(calm.metrics["diverged"]) == 0.0


def test_the_c_engine_s_callbacks_compute_with_numpy_only(built, monkeypatch):
    """JAX hands a pure_callback jax.Arrays; host arithmetic on them dispatches JAX work from inside
    the computation that waits for the callback, which hung CI once under load (the thread-count
    test, 2026-11-28: `qpos + qpos_rest` in _initial_state waited forever). The host step and the
    forward pass see NumPy arrays."""
    import footforge.envs.engine_mujoco as engine_mujoco

    seen = []
    original = engine_mujoco.MujocoPhysics._initial_state

    def spy(self, *arrays):
        seen.append({type(a) for a in arrays})
        return original(self, *arrays)

    monkeypatch.setattr(engine_mujoco.MujocoPhysics, "_initial_state", spy)
    _, env = _pair(built, "flat", "ball", "B")
    states = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 2))
    jax.jit(jax.vmap(env.step))(states, jp.zeros((2, env.action_size)))
    assert seen and all(kinds == {np.ndarray} for kinds in seen), seen
