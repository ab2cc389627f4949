"""MJX locomotion environments: registry, observation layout, reset/step, rewards, termination."""

import dataclasses
import math
from dataclasses import replace

import jax
import jax.numpy as jp
import numpy as np
import pytest

from footforge import envs
from footforge.envs import observation_layout, rewards
from footforge.envs.anymal import GEOM_BASE
from footforge.envs.config import EnvConfig, ObservationConfig, ObservationTerm, RewardConfig
from footforge.envs.contacts import ground_contacts
from footforge.envs.locomotion import LocomotionEnv
from footforge.errors import InputError

from conftest import float64_stance


def test_registry_and_its_errors():
    assert [r for r in envs.registry() if r[0] == "flat"] == [
        ("flat", "ball", "B"),
        ("flat", "aff", "B"),
        ("flat", "aff", "BH"),
        ("flat", "aof", "B"),
        ("flat", "aof", "BH"),
    ]
    assert [r for r in envs.registry() if r[0] == "rough"] == [
        ("rough", "ball", "B"),
        ("rough", "ball", "P"),
        ("rough", "aff", "B"),
        ("rough", "aff", "P"),
        ("rough", "aff", "BH"),
        ("rough", "aff", "PH"),
        ("rough", "aof", "B"),
        ("rough", "aof", "P"),
        ("rough", "aof", "BH"),
        ("rough", "aof", "PH"),
    ]
    with pytest.raises(InputError, match="not available for the flat task"):
        envs.default_config("flat", "aof", "P")
    with pytest.raises(InputError, match="ball foot has none"):
        envs.default_config("flat", "ball", "BH")
    with pytest.raises(InputError, match="unknown task 'stairs'"):
        envs.default_config("stairs", "aof", "B")
    with pytest.raises(InputError, match="unknown feet 'full'"):
        envs.default_config("flat", "full", "B")


def test_observation_layout_is_documented_and_sized():
    b, bh = EnvConfig(policy="B"), EnvConfig(policy="BH")
    assert observation_layout.size(b, 16) == 48  # the baseline's 48
    assert observation_layout.size(bh, 8) == 48 + 16 and observation_layout.size(bh, 16) == 48 + 32
    assert [name for name, _ in observation_layout.layout(bh, 16)][-2:] == ["foot_joint_pos", "foot_joint_vel"]
    # Velocity actions need the 12 PD targets observed (ObservationConfig.pd_targets); under both
    # tasks' position actions the target is default + scale x the observed last action already.
    flat, rough = envs.default_config("flat", "aof", "BH"), envs.default_config("rough", "aof", "PH")
    assert flat.action == rough.action == "position"
    assert not flat.observations.pd_targets and not rough.observations.pd_targets
    velocity = dataclasses.replace(flat, action="velocity", observations=ObservationConfig(pd_targets=True))
    assert observation_layout.layout(velocity, 16)[7] == ("pd_target", 12)
    assert observation_layout.size(velocity, 16) == 48 + 12 + 32 and observation_layout.size(flat, 16) == 48 + 32
    assert "pd_target" not in dict(observation_layout.layout(flat, 16))
    # Each group is declared once, in ObservationConfig: its reading function says what it holds
    # and in which unit, and every group is read by some policy type.
    groups = [
        f.name
        for f in dataclasses.fields(ObservationConfig)
        if isinstance(getattr(bh.observations, f.name), ObservationTerm)
    ]
    assert all(observation_layout.description(bh, name) for name in groups)
    read = {name for config in (b, bh, velocity, rough) for name, _ in observation_layout.layout(config, 16)}
    assert read == set(groups)


RICHEST = {"ball": "B", "aff": "BH", "aof": "BH"}


def _flat_envs(built, physics):
    """Per feet, the richest flat policy type's env under `physics` with reset and step compiled
    once, a reset and 3 steps of random actions: {feet: (env, states, jitted step)}. Pushes are
    off: the zero-action tests measure standing, not push recovery."""
    out = {}
    for feet, policy in RICHEST.items():
        config = envs.default_config("flat", feet, policy)
        env = envs.make(
            "flat",
            feet,
            policy,
            build_dir=str(built[feet][0]),
            pushes=replace(config.pushes, enabled=False),
            physics=physics,
        )
        step = jax.jit(env.step)
        states = [jax.jit(env.reset)(jax.random.PRNGKey(0))]
        for k in jax.random.split(jax.random.PRNGKey(1), 3):
            states.append(step(states[-1], jax.random.normal(k, (env.action_size,))))
        out[feet] = (env, states, step)
    return out


@pytest.fixture(scope="module")
def rollouts(built):
    """_flat_envs under MuJoCo's C engine, the CPU's physics (`--physics auto` on a CPU): the task's
    maths are the same under either engine (tests/test_engines.py), and it compiles in a fraction of
    MJX's time."""
    return _flat_envs(built, "mujoco")


@pytest.fixture(scope="module")
def rollouts_mjx(built):
    """_flat_envs in MJX (float32), for the tests of MJX's own stance physics (slow run)."""
    return _flat_envs(built, "mjx")


def test_reset_and_step_every_registered_env(rollouts, built):
    for feet, (env, states, _) in rollouts.items():
        n_passive = {"ball": 0, "aff": 8, "aof": 16}[feet]
        assert len(env.robot.passive_qpos) == n_passive
        assert env.observation_size == observation_layout.size(env.config, n_passive)
        for state in states:
            assert state.obs.shape == (env.observation_size,)
            assert bool(jp.isfinite(state.obs).all()) and bool(jp.isfinite(state.reward))
            assert float(jp.abs(state.obs).max()) <= env.config.observations.clip
        assert set(states[-1].metrics) == set(states[0].metrics)
        assert {f"reward/{t}" for t in rewards.terms(env.config.rewards)} <= set(states[-1].metrics)
        # The flat task starts at the build's `stand` keyframe (at rest under the published
        # default targets), the PD targets at those defaults, joint velocities within +-0.1 rad/s.
        first = states[0]
        np.testing.assert_allclose(first.pipeline_state.qpos, env.robot.stand_qpos, atol=1e-6)
        np.testing.assert_allclose(first.info["target"], env.robot.default_q, atol=1e-9)
        np.testing.assert_allclose(first.pipeline_state.ctrl[env.robot.actuator_ids], env.robot.default_q, atol=1e-9)
        qd = np.asarray(first.pipeline_state.qvel[env.robot.actuated_dof])
        assert np.abs(qd).max() <= env.config.reset.joint_vel_max and np.abs(qd).max() > 0
        assert float(jp.abs(first.pipeline_state.qvel[:6]).max()) == 0.0
        # The other policy types of these feet differ from the richest only in the observation:
        # each one's observation of the stepped state is sized by its layout, finite, and a
        # prefix of the richest one's (noise off).
        quiet = replace(env.config.observations, noise=False)
        full = LocomotionEnv(replace(env.config, observations=quiet), env.robot).observe(
            states[-1].pipeline_state, states[-1].info, jax.random.PRNGKey(0)
        )
        # Position actions: the last step's targets are default + 0.5 x its clipped action within
        # the joint ranges. With ObservationConfig.pd_targets (for velocity actions) the PD
        # targets' slice holds them minus the defaults: what the joint angles do not reveal, as
        # they lag the targets by torque / kp.
        lo, hi = env.robot.q_limits[:, 0], env.robot.q_limits[:, 1]
        last = np.clip(
            np.asarray(jax.random.normal(jax.random.split(jax.random.PRNGKey(1), 3)[-1], (env.action_size,))), -1.0, 1.0
        )  # the fixture's last action
        target = np.clip(np.asarray(env.robot.default_q, np.float64) + 0.5 * last, lo, hi)
        np.testing.assert_allclose(states[-1].info["target"], target, atol=1e-5)
        seeing = LocomotionEnv(replace(env.config, observations=replace(quiet, pd_targets=True)), env.robot)
        layout = observation_layout.layout(seeing.config, n_passive)
        start = sum(w for _, w in layout[: [n for n, _ in layout].index("pd_target")])
        seen = seeing.observe(states[-1].pipeline_state, states[-1].info, jax.random.PRNGKey(0))
        np.testing.assert_allclose(seen[start : start + 12], target - env.robot.default_q, atol=1e-5)
        q = np.asarray(states[-1].pipeline_state.qpos[env.robot.actuated_qpos])
        assert np.abs(target - q).max() > 0.05
        for task, f, policy in envs.registry():
            if task == "flat" and f == feet:
                other = LocomotionEnv(
                    replace(
                        envs.default_config("flat", feet, policy), observations=quiet, build_dir=str(built[feet][0])
                    ),
                    env.robot,
                )
                obs = other.observe(states[-1].pipeline_state, states[-1].info, jax.random.PRNGKey(0))
                assert obs.shape == (other.observation_size,)
                np.testing.assert_allclose(obs, full[: other.observation_size], atol=1e-6)


def test_reward_terms_on_known_states():
    cfg = RewardConfig()
    Q = rewards.Quantities
    assert float(
        rewards.lin_vel_xy(Q(command=jp.array([1.0, 0.0, 0.0]), lin_vel=jp.array([1.0, 0.0, 0.0])), sigma=0.25)
    ) == pytest.approx(1.0)
    assert float(
        rewards.lin_vel_xy(Q(command=jp.array([1.0, 0.0, 0.0]), lin_vel=jp.array([0.5, 0.0, 0.0])), sigma=0.25)
    ) == pytest.approx(math.exp(-1))
    assert float(
        rewards.yaw_rate(Q(command=jp.array([0.0, 0.0, 0.5]), ang_vel=jp.zeros(3)), sigma=0.25)
    ) == pytest.approx(math.exp(-1))
    assert float(rewards.lin_vel_z(Q(lin_vel=jp.array([0.0, 0.0, 0.3])))) == pytest.approx(0.09)
    assert float(rewards.ang_vel_xy(Q(ang_vel=jp.array([0.1, 0.2, 5.0])))) == pytest.approx(0.05)
    assert float(rewards.orientation(Q(gravity=jp.array([0.0, 0.0, -1.0])))) == 0.0
    tilt = math.radians(30)  # base rolled by 30 deg: gravity has sin(30) along base y
    assert float(rewards.orientation(Q(gravity=jp.array([0.0, math.sin(tilt), -math.cos(tilt)])))) == pytest.approx(
        0.25
    )
    assert float(rewards.base_height(Q(base_height=0.42), target_m=0.52)) == pytest.approx(0.01)
    assert float(rewards.torques(Q(torques=jp.full(12, 10.0)))) == pytest.approx(1200.0)
    assert float(rewards.joint_acc(Q(joint_vel=jp.ones(12), last_joint_vel=jp.zeros(12)))) == pytest.approx(12.0)
    assert float(rewards.action_rate(Q(action=jp.ones(12), last_action=jp.ones(12)))) == 0.0
    assert float(rewards.hip(Q(haa_offset=jp.array([0.1, -0.1, 0.0, 0.0])))) == pytest.approx(0.2)
    # Each term is declared once, in RewardConfig: its function is the one above, its scale a
    # number, its parameters the defaults used above.
    terms = rewards.terms(cfg)
    assert list(terms)[:12] == [  # in declaration order; a term added later follows
        "lin_vel_xy",
        "yaw_rate",
        "lin_vel_z",
        "ang_vel_xy",
        "orientation",
        "base_height",
        "torques",
        "joint_acc",
        "action_rate",
        "hip",
        "feet_air_time",
        "stand_still",
    ]
    assert all(term.compute is getattr(rewards, name) and isinstance(term.scale, float) for name, term in terms.items())
    assert {name: term.params for name, term in list(terms.items())[:12] if term.params} == {
        "lin_vel_xy": {"sigma": 0.25},
        "yaw_rate": {"sigma": 0.25},
        "base_height": {"target_m": 0.52},
        "feet_air_time": {"target_s": 0.5},
    }
    assert cfg.feet_air_time.scale == cfg.stand_still.scale == 0.0  # not among the paper's terms: off unless asked for
    # stand_still: |q - default| summed, only under a planar command below 0.1 m/s.
    offset = jp.array([0.1, -0.2, 0.0] * 4)
    assert float(rewards.stand_still(Q(joint_offset=offset, command=jp.array([0.05, 0.05, 0.8])))) == pytest.approx(1.2)
    assert float(rewards.stand_still(Q(joint_offset=offset, command=jp.array([0.3, 0.0, 0.0])))) == 0.0


def test_feet_air_time_pays_touchdowns_after_long_enough_steps():
    """legged_gym's bookkeeping (LocomotionEnv._feet_steps) on a scripted contact sequence: LF
    touches, lifts for 30 policy steps (0.6 s at 50 Hz), lands; RF lifts for 10 steps (0.2 s). Each
    touchdown reports the steps spent in the air x dt; the term pays air time - 0.5 s per
    touchdown (+0.1 for LF, -0.3 for RF) under a moving command, nothing under a zero one."""
    from types import SimpleNamespace

    dt = 0.02
    lf = [True] + [False] * 30 + [True] * 3
    rf = [True] * 5 + [False] * 10 + [True] * 19
    info = LocomotionEnv._no_steps()
    touchdowns = []
    for contact in zip(lf, rf, [True] * len(lf), [True] * len(lf)):
        stub = SimpleNamespace(
            foot_contacts=lambda data, c=contact: jp.array(c),
            config=SimpleNamespace(policy_dt=dt, rewards=RewardConfig().with_scales(feet_air_time=1.0)),
        )
        out = LocomotionEnv._feet_steps(stub, None, info)
        info = {k: out[k] for k in info}
        touchdowns.append(np.asarray(out["touchdown_air_time"]))
    touchdowns = np.array(touchdowns)
    assert touchdowns[31, 0] == pytest.approx(30 * dt) and touchdowns[15, 1] == pytest.approx(10 * dt)
    assert np.count_nonzero(touchdowns) == 2  # one touchdown each; a foot on the ground earns nothing
    term = RewardConfig().feet_air_time  # target_s 0.5
    both = jp.array([0.6, 0.2, 0.0, 0.0])
    moving = rewards.Quantities(command=jp.array([0.5, 0.0, 0.0]), touchdown_air_time=both)
    assert float(term(moving)) == pytest.approx((0.6 - 0.5) + (0.2 - 0.5))
    still = moving._replace(command=jp.zeros(3))
    assert float(term(still)) == 0.0


def test_ground_contacts_count_base_and_knees():
    category = jp.array([0, GEOM_BASE, 3, 4, 5, 6])  # geom 0 is the floor
    geoms = jp.array([[0, 1], [0, 3], [4, 0], [0, 5]])
    base, knees = ground_contacts(category, 0, geoms, jp.array([0.01, -0.001, -0.002, 0.02]))
    assert not bool(base) and int(knees) == 2  # thighs of legs 0 and 1 touch; leg 2's is 2 cm above
    base, knees = ground_contacts(category, 0, geoms, jp.array([-0.001, 0.01, 0.01, 0.01]))
    assert bool(base) and int(knees) == 0


def test_base_and_knee_contacts_are_measured_on_flat_ground(rollouts, built):
    """The base's and thighs' colliders are off in MJX (they only end episodes, and were most of
    the contact slots every Newton iteration solves): their ground contact is geometric. Checked
    against CPU MuJoCo's own collisions on the build's full model, pose by pose."""
    from types import SimpleNamespace

    import mujoco

    from footforge.envs.anymal import GEOM_FOOT, load_robot

    _, states, _ = rollouts["aof"]  # a reset's joint angles
    env = envs.make("flat", "aof", RICHEST["aof"], build_dir=str(built["aof"][0]), physics="mjx")  # not compiled
    mjx_model, category = env.robot.model, env.robot.geom_category
    full = load_robot(env.config, for_mjx=False).model  # every collider of the build
    body = (category > 0) & (category < GEOM_FOOT)  # base and thighs
    assert body.sum() >= 5 and not (mjx_model.geom_contype[body] | mjx_model.geom_conaffinity[body]).any()
    assert (full.geom_contype[body] | full.geom_conaffinity[body]).all()
    assert int(mjx_model.geom_contype.sum() + mjx_model.geom_conaffinity.sum()) < int(
        full.geom_contype.sum() + full.geom_conaffinity.sum()
    )
    data = mujoco.MjData(full)

    def both(z, quat=(1.0, 0.0, 0.0, 0.0)):  # (geometric flags, MuJoCo's contact flags) at one pose
        data.qpos[:] = np.asarray(states[0].pipeline_state.qpos)
        data.qpos[2], data.qpos[3:7] = z, quat
        mujoco.mj_forward(full, data)
        flags = env.contact_flags(SimpleNamespace(geom_xpos=data.geom_xpos, geom_xmat=data.geom_xmat.reshape(-1, 3, 3)))
        pairs = jp.asarray(data.contact.geom[: data.ncon].copy()) if data.ncon else jp.zeros((0, 2), jp.int32)
        dists = jp.asarray(data.contact.dist[: data.ncon].copy())
        touching = ground_contacts(jp.asarray(category), env.robot.floor_geom, pairs, dists)
        return (bool(flags[0]), int(flags[1])), (bool(touching[0]), int(touching[1]))

    standing, standing_mujoco = both(float(env.robot.stand_qpos[2]))
    assert standing == standing_mujoco == (False, 0)
    sunk, sunk_mujoco = both(0.05)  # base 5 cm over the ground: its box and the thighs reach under it
    assert sunk == sunk_mujoco == (True, 4)
    rolled, rolled_mujoco = both(0.6, (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0))  # on its side, 0.6 m up
    assert rolled == rolled_mujoco == (False, 0)


def test_base_on_the_ground_terminates_and_time_out_is_a_truncation(rollouts):
    env, states, step = rollouts["ball"]
    state = states[0]
    data = state.pipeline_state
    sunk = step(state.replace(pipeline_state=data.replace(qpos=data.qpos.at[2].set(0.05))), jp.zeros(12))
    assert float(sunk.done) == 1.0 and float(sunk.info["time_out"]) == 0.0  # a fall, not a time-out
    np.testing.assert_allclose(sunk.pipeline_state.qpos, env.robot.stand_qpos, atol=1e-6)  # restarted standing
    assert float(sunk.reward) == pytest.approx(env.config.rewards.fall)  # the fall penalty survives the clip
    assert float(sunk.metrics["reward/fall"]) == pytest.approx(env.config.rewards.fall)
    last = state.replace(info=state.info | {"episode_step": jp.array(env.config.episode_steps - 1, jp.int32)})
    after = step(last, jp.zeros(12))
    assert float(after.info["time_out"]) == 1.0 and float(after.done) == 1.0
    assert int(after.info["episode_step"]) == 0
    assert float(after.metrics["reward/fall"]) == 0.0 and float(after.reward) >= 0.0  # a time-out is no fall


def test_position_actions_set_the_target_and_velocity_actions_integrate_onto_it(rollouts):
    """Flat task (position actions): target = default + 0.5 x clip(a, +-1), whatever the previous
    target; the reward and the next observation see the clipped action. Velocity actions (the
    flat baseline's, an option): target_t = target_t-1 + 13.5 x clip(a) x dt."""
    env, states, step = rollouts["ball"]
    state = states[1]  # targets away from the defaults
    lo, hi = env.robot.q_limits[:, 0], env.robot.q_limits[:, 1]
    action = jp.linspace(-3.0, 3.0, 12)  # half of it beyond the clip
    after = step(state, action)
    clipped = np.clip(np.asarray(action), -1.0, 1.0)
    expected = np.clip(np.asarray(env.robot.default_q) + 0.5 * clipped, lo, hi)
    np.testing.assert_allclose(after.info["target"], expected, atol=1e-6)
    np.testing.assert_allclose(after.pipeline_state.ctrl[env.robot.actuator_ids], expected, atol=1e-6)
    np.testing.assert_allclose(after.info["last_action"], clipped, atol=1e-7)
    # A zero action returns the target to the defaults, although the joints are elsewhere.
    again = step(after, jp.zeros(12))
    np.testing.assert_allclose(again.info["target"], env.robot.default_q, atol=1e-7)
    moved = np.abs(np.asarray(again.pipeline_state.qpos[env.robot.actuated_qpos]) - env.robot.default_q).max()
    assert moved > 1e-3
    # The same clipped action under velocity actions moves the previous target at 13.5 rad/s.
    velocity = LocomotionEnv(replace(env.config, action="velocity", action_scale=13.5), env.robot)
    previous = np.asarray(state.info["target"])
    integrated = velocity.joint_targets(previous, velocity.clip_action(action))
    np.testing.assert_allclose(integrated, np.clip(previous + 13.5 * clipped * env.config.policy_dt, lo, hi), atol=1e-6)
    np.testing.assert_allclose(velocity.joint_targets(previous, jp.zeros(12)), np.clip(previous, lo, hi), atol=1e-7)


@pytest.fixture(scope="module")
def zero_action_episodes(rollouts_mjx):
    """Per feet: a full 20 s flat episode of zero actions from reset in the default environment
    (footforge.validate.stance.env_stance: figures after the first 0.5 s)."""
    from footforge.validate.stance import env_stance

    return {
        feet: env_stance(env, states[0], seconds=env.config.episode_length_s - env.config.policy_dt, step=step)
        for feet, (env, states, step) in rollouts_mjx.items()
    }


@pytest.fixture(scope="module")
def ten_second_stances(rollouts_mjx):
    """Per feet: issue 12's stance measure, 10 s of zero actions from the same reset."""
    from footforge.validate.stance import env_stance

    return {
        feet: env_stance(env, states[0], seconds=10.0, step=step) for feet, (env, states, step) in rollouts_mjx.items()
    }


@pytest.mark.slow  # 3 x 1000 single-robot steps
@pytest.mark.timeout(600)  # explicit budget: several times its time on 2 quiet cores
@pytest.mark.parametrize("feet", list(RICHEST))
def test_zero_action_robot_stands_a_whole_episode(zero_action_episodes, feet):
    """The flat task's robot, given zero actions, stays up for a full 20 s episode: no fall, no
    divergence, its base never below 0.25 m (the action model of EnvConfig.action)."""
    stance = zero_action_episodes[feet]
    assert not stance.fell and stance.base_height_min_m > 0.25, (feet, stance)


@pytest.mark.slow  # shares the episodes above
@pytest.mark.timeout(600)  # explicit budget: several times its time on 2 quiet cores
@pytest.mark.parametrize("feet", list(RICHEST))
def test_the_default_environment_holds_a_robot_still(ten_second_stances, feet):
    """Issue 12's stance target in the default training environment (contact_model 'stance',
    MJX's float32): 10 s of zero actions from the reset's random joint velocities, pushes off; after the
    first 0.5 s the base sinks less than 10 mm and no foot slides more than 5 mm. With
    contact_model 'fast' the same robots sink 150-220 mm in 10-20 s, and the adaptive feet crept
    11-13 mm in 10 s here while their passive joints' armature was 1e-5 kg m^2 (the parameter
    file's is 1e-3; benchmarks/log/2026-11-21_to_26.md)."""
    stance = ten_second_stances[feet]
    assert not stance.fell, stance
    assert stance.drop_after_settle_m < 0.010, stance
    assert stance.slip_after_settle_m < 0.005, stance


def test_the_build_contact_model_is_refused_without_a_converged_solve(built):
    """contact_model 'build' at the environment's 5 ms step diverges with fewer than 16 Newton and
    50 line-search iterations (benchmarks/contact_sweep.py): refused with the keys to change."""
    from footforge.envs.anymal import load_robot

    config = EnvConfig(feet="ball", build_dir=str(built["ball"][0]), contact_model="build")
    for iterations, ls_iterations in ((4, 8), (16, 8), (100, 20)):
        with pytest.raises(InputError, match="solver_iterations >= 16 and solver_ls_iterations >= 50"):
            load_robot(replace(config, solver_iterations=iterations, solver_ls_iterations=ls_iterations))
    robot = load_robot(replace(config, solver_iterations=16, solver_ls_iterations=50))
    assert robot.model.opt.cone == 1 and robot.model.opt.impratio == 10.0  # elliptic, the build's


@pytest.mark.slow  # two compiled environments at 16 Newton iterations: about 4 minutes on 2 cores
@pytest.mark.timeout(900)  # explicit budget: several times its time on 2 quiet cores
@pytest.mark.parametrize("feet", ["ball", "aof"])
def test_zero_action_robot_holds_its_stance_with_the_build_contact(built, feet):
    """Issue 12's stance target in MJX with contact_model 'build' (the scene's elliptic contact,
    converged at 16/50 iterations, at its 2.5 ms step): from the reset's randomised joint
    velocities, zero actions for 10 s; no fall, and after the first 0.5 s the base sinks less than
    10 mm and no foot slides more than 5 mm. (At 5 ms the ball robot slid 51 mm, and AOF diverged
    within 0.03 s.)"""
    from footforge.validate.stance import env_stance

    config = envs.default_config("flat", feet, RICHEST[feet], "build")
    assert (config.sim_dt, config.solver_iterations, config.solver_ls_iterations) == (0.0025, 16, 50)
    env = envs.from_config(replace(config, build_dir=str(built[feet][0]), pushes=replace(config.pushes, enabled=False)))
    stance = env_stance(env, jax.jit(env.reset)(jax.random.PRNGKey(0)), seconds=10.0)
    assert not stance.fell and stance.drop_after_settle_m < 0.010, (feet, stance)
    assert stance.slip_after_settle_m < 0.005, (feet, stance)


def test_contact_models_are_refused_where_they_diverge(built):
    """contact_model 'stance' runs at sim_dt <= 2.5 ms with at least its feet's Newton and
    line-search iterations in its precision (float32 ball 8/16, AFF 16/16, AOF 8/16; float64 AFF
    and AOF 16/16, where they were measured stable): anything else is refused before any model is
    loaded, naming the keys to change. envs.with_contact_model and envs.with_float64_physics set
    what it needs."""
    from footforge.envs.anymal import load_robot
    from footforge.envs.contact_physics import resolve

    for feet, float32_iterations, float64_iterations in (("ball", 8, 8), ("aff", 16, 16), ("aof", 8, 16)):
        config = EnvConfig(feet=feet, build_dir=str(built[feet][0]), solver_iterations=4, solver_ls_iterations=8)
        stance = envs.with_contact_model(config, "stance")
        assert (stance.contact_model, stance.sim_dt, stance.decimation) == ("stance", 0.0025, 8)
        assert (stance.solver_iterations, stance.solver_ls_iterations) == (float32_iterations, 16)
        assert stance.policy_dt == pytest.approx(config.policy_dt)
        with pytest.raises(
            InputError,
            match=rf"solver_iterations >= {float32_iterations} and solver_ls_iterations "
            rf">= 16 in float32 physics .* on {feet} feet",
        ):
            load_robot(replace(stance, solver_iterations=float32_iterations - 1))
        stiff = envs.with_float64_physics(stance)
        assert (stiff.float64_physics, stiff.solver_iterations, stiff.solver_ls_iterations) == (
            True,
            float64_iterations,
            16,
        )
        if float64_iterations > float32_iterations:
            with pytest.raises(InputError, match="solver_iterations >= 16 .* in float64 physics") as e:
                load_robot(replace(stance, float64_physics=True))
            assert "with_float64_physics" in e.value.fix
        with pytest.raises(InputError, match=r"sim_dt <= 0.0025 s \(given 0.005\)") as e:
            load_robot(replace(stance, sim_dt=0.005, decimation=4))
        assert "decimation=8" in e.value.fix
        model = load_robot(stance).model
        assert model.opt.cone == 0 and model.opt.impratio == 10.0  # pyramidal
        # Euler; the float32 impedance is softer for the adaptive feet (envs.contact_physics)
        solimp = (0.99, 0.999, 0.001) if feet == "ball" else (0.97, 0.995, 0.001)
        assert model.opt.integrator == 0 and np.allclose(model.geom_solimp[:, :3], solimp)
        # ... and for every feet on a heightfield, whose MJX contacts exist only while penetrating.
        assert resolve("stance", feet, float64_physics=False, on_heightfield=True).solimp == (0.97, 0.995, 0.001)
        assert resolve("stance", feet, float64_physics=True, on_heightfield=True).solimp == (0.99, 0.999, 0.001)
        # The adaptive feet in float32 rest on a softer normal, every geom alike (envs.contact_physics);
        # ball feet and float64 keep the build's solref.
        built_solref = load_robot(replace(stance, contact_model="fast", sim_dt=0.005, decimation=4)).model.geom_solref
        if feet == "ball":
            assert np.array_equal(model.geom_solref, built_solref)
        else:
            assert np.all(model.geom_solref == (-10000.0, -400.0)) and not np.any(built_solref == -400.0)
            assert np.allclose(load_robot(stiff).model.geom_solimp[:, :3], (0.99, 0.999, 0.001))
            assert np.array_equal(load_robot(stiff).model.geom_solref, built_solref)
    # Finer settings than stance needs are kept.
    fine = replace(EnvConfig(feet="ball"), sim_dt=0.001, decimation=20, solver_iterations=50, solver_ls_iterations=50)
    kept = envs.with_contact_model(fine, "stance")
    assert (kept.sim_dt, kept.decimation, kept.solver_iterations, kept.solver_ls_iterations) == (0.001, 20, 50, 50)


def test_the_adaptive_feet_s_float64_stance_survives_an_untrained_policy_s_actions(built):
    """Float64 'stance' on AFF feet steps at 16 Newton iterations (its row in
    envs.contact_physics), refuses fewer, and no robot diverges there under an
    untrained policy's random actions (footforge.envs.stability, CPU MuJoCo). What fewer
    iterations do (robots thrown at 8/16) is an experiment: benchmarks/divergence_history.py."""
    from footforge.envs.anymal import load_robot
    from footforge.envs.stability import divergence_times

    float32 = envs.with_contact_model(EnvConfig(feet="aff", build_dir=str(built["aff"][0])), "stance")
    stance = envs.with_float64_physics(float32)
    assert (float32.solver_iterations, stance.solver_iterations, stance.solver_ls_iterations) == (16, 16, 16)
    with pytest.raises(InputError, match="solver_iterations >= 16 .* in float64 physics"):
        load_robot(replace(stance, solver_iterations=8))
    assert divergence_times(stance, robots=4, seconds=4.0, seed=0) == [None] * 4


def test_float64_physics_is_refused_without_jax_s_x64_mode(built):
    """EnvConfig.float64_physics needs JAX's process-wide x64 mode (off in this test process): the
    environment refuses to start, naming the call that turns it on."""
    import jax

    assert not jax.config.read("jax_enable_x64")
    with pytest.raises(InputError, match="x64") as e:
        envs.make("flat", "aff", "B", build_dir=str(built["aff"][0]), float64_physics=True)
    assert "enable_float64_physics" in e.value.fix


@pytest.mark.slow  # a subprocess (x64 is process-wide) compiling at 16 (AFF) or 30 (AOF) iterations: 4-6 minutes each
@pytest.mark.timeout(1800)  # explicit budget: several times its time on 2 quiet cores
@pytest.mark.parametrize("feet", ["aff", "aof"])
def test_the_stance_contact_holds_an_adaptive_foot_robot_still_in_float64(built, feet):
    """Issue 12's stance target in the MJX training environment on the adaptive feet: the default
    contact_model 'stance' with float64_physics, zero actions for 10 s from the reset's random
    joint velocities: no fall, and after the first 0.5 s the base sinks less than 10 mm and no
    foot slides more than 5 mm. The policy's side stays float32 while the physics runs in float64."""
    result = float64_stance("flat", feet, built[feet][0].parent)
    assert result["physics"] == "float64"
    assert (result["obs"], result["reward"], result["metrics"]) == ("float32", "float32", ["float32"])
    assert not result["fell"], result
    assert result["drop_after_settle_m"] < 0.010, result
    assert result["slip_after_settle_m"] < 0.005, result


@pytest.mark.slow  # its own compiled environment: about 2 minutes on 2 cores
@pytest.mark.timeout(600)  # explicit budget: several times its time on 2 quiet cores
def test_privileged_critic_observations(built):
    """EnvConfig.privileged_critic: Brax's dict observation, the policy's slice unchanged and the
    critic's extra slice physical: at rest the feet carry the robot's weight."""
    config = envs.default_config("flat", "ball", "B")
    env = envs.make(
        "flat",
        "ball",
        "B",
        build_dir=str(built["ball"][0]),
        privileged_critic=True,
        pushes=replace(config.pushes, enabled=False),
    )
    n = env.observation_size["state"][0]
    assert n == 48 and env.observation_size["privileged_state"] == (n + 3 + 4 + 140 + 1,)
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    step = jax.jit(env.step)
    for _ in range(25):  # 0.5 s standing
        state = step(state, jp.zeros(12))
    obs = state.obs
    assert obs["state"].shape == (n,) and obs["privileged_state"].shape == env.observation_size["privileged_state"]
    np.testing.assert_array_equal(obs["privileged_state"][:n], obs["state"])
    extra = np.asarray(obs["privileged_state"][n:])
    lin, _, _ = env.base_state(state.pipeline_state)
    np.testing.assert_allclose(extra[:3], np.asarray(lin) * env.config.observations.base_lin_vel.scale, atol=1e-6)
    forces = extra[3:7]
    assert np.all(forces > 0.1)  # every foot bears load
    assert abs(forces.sum() - 1.0) < 0.05, forces  # and together the robot's weight (vertical = normal here)
    assert extra[-1] == pytest.approx(float(env.robot.model.geom_friction[env.robot.floor_geom, 0]))


def test_a_build_that_does_not_fit_is_refused_with_the_rebuild_command(built, tmp_path):
    """ensure_built refuses, never silently uses or rebuilds, a build of another variant, of an
    older build format (no `stand` keyframe), or whose inputs changed since it was built."""
    import json
    import shutil

    from footforge.envs.anymal import ensure_built

    params = tmp_path / "params.yaml"
    shutil.copy(json.loads((built["ball"][0] / "build_report.json").read_text())["inputs"]["params"]["path"], params)

    def variant_of(change):
        folder = tmp_path / f"build_{len(list(tmp_path.iterdir()))}"
        shutil.copytree(built["ball"][0], folder)
        data = json.loads((folder / "build_report.json").read_text())
        change(data)
        (folder / "build_report.json").write_text(json.dumps(data))
        return folder

    good = variant_of(lambda d: None)
    assert ensure_built(replace(envs.default_config("flat", "ball", "B"), build_dir=str(good))) == good
    cases = {
        "holds the 'ball' variant, not 'aff'": (variant_of(lambda d: None), "aff"),
        "built by an older footforge (build format 1": (variant_of(lambda d: d.update(format=1)), "ball"),
        f"input 'params' ({params}) changed since": (
            variant_of(lambda d: d["inputs"].update(params={"path": str(params), "sha256": "0" * 64})),
            "ball",
        ),
    }
    for expected, (folder, feet) in cases.items():
        config = replace(envs.default_config("flat", feet, "B"), build_dir=str(folder))
        with pytest.raises(InputError) as e:
            ensure_built(config)
        assert expected in str(e.value), str(e.value)
        assert f"footforge build --variant {feet} --out {folder}" in str(e.value)


def _signature(state):
    return [
        (jax.tree_util.keystr(path), x.shape, x.dtype, x.weak_type)
        for path, x in jax.tree_util.tree_flatten_with_path(state)[0]
    ]


def test_step_returns_the_types_it_takes(rollouts):
    """A step's state has reset's exact types (shape, dtype, weak type), so a jitted step compiles
    once: a weakly typed metric once made every second call compile again (100x slower)."""
    for feet, (_, states, step) in rollouts.items():
        for state in states[1:]:
            assert _signature(state) == _signature(states[0]), feet
        assert step._cache_size() == 1, feet


def test_a_non_finite_reward_term_or_state_ends_the_episode_as_diverged(rollouts):
    """The total reward is clipped at zero, which turns -inf or NaN into 0: finiteness is checked
    before the clip. A non-finite reward term (here joint_acc, through the previous joint
    velocities) or state, or a speed past EnvConfig.diverged_speed, ends the robot's episode as a
    fall, with the `diverged` metric at 1 and neither NaN rewards nor NaN observations."""
    env, states, step = rollouts["ball"]
    state = states[1]
    assert float(step(state, jp.zeros(12)).metrics["diverged"]) == 0.0
    data = state.pipeline_state
    poisoned = {
        "inf term": state.replace(info=state.info | {"last_joint_vel": jp.full(12, jp.inf, jp.float32)}),
        "NaN term": state.replace(info=state.info | {"last_joint_vel": jp.full(12, jp.nan, jp.float32)}),
        "NaN state": state.replace(pipeline_state=data.replace(qvel=data.qvel.at[6].set(jp.nan))),
        # blown up but finite, as AOF's physics did in the H100 campaign (EnvConfig.diverged_speed)
        "huge speed": state.replace(pipeline_state=data.replace(qvel=data.qvel.at[0].set(1e8))),
    }
    for name, bad in poisoned.items():
        after = step(bad, jp.zeros(12))
        assert float(after.metrics["diverged"]) == 1.0, name
        assert float(after.done) == 1.0 and float(after.info["time_out"]) == 0.0, name  # ended, as a fall
        assert float(after.reward) == pytest.approx(env.config.rewards.fall), name
        assert float(after.metrics["reward/joint_acc"]) == 0.0, name
        assert bool(jp.isfinite(after.obs).all()) and bool(jp.isfinite(after.pipeline_state.qvel).all()), name


def test_evaluation_reports_robots_whose_simulation_diverged(built, monkeypatch):
    """footforge.rl.evaluate counts the diverged robots (among the falls) and comparison.md shows them."""
    from footforge.rl import evaluate as evaluation

    config = replace(
        envs.default_config("flat", "ball", "B"),
        build_dir=str(built["ball"][0]),
        pushes=replace(envs.default_config("flat", "ball", "B").pushes, enabled=False),
        physics="mujoco",
    )

    class Diverging(LocomotionEnv):
        """Robot 0's joint_acc term becomes NaN at its third step (its state stays finite)."""

        def step(self, state, action):
            poison = jp.where((state.info["step"] == 2) & (state.info["robot"] == 0), jp.nan, 0.0)
            info = state.info | {"last_joint_vel": state.info["last_joint_vel"] + poison}
            return super().step(state.replace(info=info), action)

        def reset(self, rng):
            state = super().reset(rng)
            return state.replace(info=state.info | {"robot": (rng[-1] % 2).astype(jp.int32)})

    env = Diverging(config)
    monkeypatch.setattr(
        evaluation, "_policy_and_env", lambda *args: (lambda obs, key: (jp.zeros(12), {}), config, "ball", 0.1, env)
    )
    monkeypatch.setattr("footforge.rl.policy_files.policy_digest", lambda path: "no files: a stand-in policy")
    keys = jax.random.split(jax.random.PRNGKey(0), 4)  # evaluate's keys: which robots are "robot 0"
    zero = int(sum(int(jax.random.split(k)[0][-1] % 2 == 0) for k in keys))
    result = evaluation.evaluate("policy", num_envs=4, seed=0)
    assert 0 < zero < 4 and result["diverged"] == zero and result["falls"] >= zero
    assert f"({zero} diverged" in evaluation.comparison_markdown([result])
    # Each fallen robot's fall time: the diverged ones at the end of their third step.
    assert len(result["fall_times_s"]) == result["falls"]
    assert result["fall_times_s"][:zero] == pytest.approx([3 * config.policy_dt] * zero)


def test_falls_are_timed_and_attributed_to_the_pushes_and_new_commands_before_them():
    """evaluate's fall times (the end of the first step a robot is down) and the events they follow:
    pushes and command changes at every multiple of their interval, a fall counted for an event
    when it comes within AFTER_EVENT_S of it."""
    from footforge.rl.evaluate import AFTER_EVENT_S, event_times, fall_times, falls_after, falls_cell

    alive = np.ones((4, 10), bool)
    alive[1, 3:] = False  # down after step 4
    alive[3, 7:] = False  # down after step 8
    assert fall_times(alive, 0.5) == [2.0, 4.0]
    assert event_times(1.5, 0.5, 10) == [1.5, 3.0, 4.5]  # steps 3, 6 and 9
    assert event_times(10.0, 0.02, 1000) == pytest.approx([10.0, 20.0])
    assert falls_after([2.0, 4.0], [1.5, 3.0, 4.5], window_s=0.5) == [2.0]
    assert falls_after([2.0, 4.0], [1.5, 3.0, 4.5], window_s=1.0) == [2.0, 4.0]
    assert falls_after([1.0], [1.5]) == []  # before the event: not its fall
    assert AFTER_EVENT_S == pytest.approx(2.0)
    result = {
        "falls": 2,
        "num_envs": 4,
        "fall_times_s": [2.0, 4.0],
        "push_times_s": [1.5],
        "falls_after_push": 1,
        "command_times_s": [3.0],
        "falls_after_command": 1,
    }
    assert falls_cell(result) == "2/4 (within 2 s of: 1 a push, 1 a new command)"
    assert falls_cell({"falls": 2, "num_envs": 4}) == "2/4"  # an evaluation written before fall times
    assert falls_cell(result | {"falls": 0, "fall_times_s": []}) == "0/4"


def test_the_forward_error_trace_averages_the_robots_still_up_and_is_silent_when_none_is():
    """evaluate's per-step trace of the forward error: the mean over the robots still up (fallen
    ones are NaN), NaN once all have fallen, without numpy's 'Mean of empty slice' warning (a
    zero-shot evaluation on feet the policy falls on printed it)."""
    import warnings

    from footforge.rl.evaluate import _mean_over_standing

    errors = np.array([[0.1, 0.3, np.nan], [0.5, np.nan, np.nan]])  # 2 robots x 3 steps
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        trace = _mean_over_standing(errors)
    assert trace[:2] == pytest.approx([0.3, 0.3]) and np.isnan(trace[2])


def test_adaptive_feet_train_at_a_physics_step_that_survives_a_policy_s_actions(built):
    """'fast' steps every feet at the baselines' 5 ms x 4, and under an untrained policy's random
    actions (footforge.envs.stability, CPU MuJoCo on the environment's model) no AOF robot
    diverges there with the parameter file's passive-joint armature of 1e-3 kg m^2. (With the
    old 1e-5 most did, and the adaptive feet stepped at 2.5 ms until 2026-11-25: an experiment,
    benchmarks/divergence_history.py.)"""
    from footforge.envs.stability import divergence_times
    from footforge.inputs.params import default_params_path

    aof = envs.default_config("flat", "aof", "B", "fast")
    assert (aof.sim_dt, aof.decimation) == (0.005, 4) and aof.policy_dt == pytest.approx(0.02)
    ball = envs.default_config("rough", "ball", "B", "fast")
    assert (ball.sim_dt, ball.decimation) == (0.005, 4)
    at_5ms = replace(aof, build_dir=str(built["aof"][0]))
    assert divergence_times(at_5ms, robots=12, seconds=10.0, seed=0) == [None] * 12
    text = default_params_path().read_text()
    assert text.count("armature: 1.0e-3") == 6  # AFF's two passive joints and AOF's four


def test_a_policy_evaluated_on_other_feet_steps_them_at_their_own_physics_step(monkeypatch):
    """A policy evaluated on other feet keeps its contact model and 20 ms policy step, at the
    physics step and solver iterations that model needs on those feet; a policy trained at a
    finer step than the other feet need keeps its own. evaluate() builds its environment
    through on_feet."""
    from footforge.rl import evaluate as evaluation

    ball = envs.default_config("flat", "ball", "B", "fast")
    on_aof = envs.on_feet(ball, "aof")
    assert (on_aof.feet, on_aof.sim_dt, on_aof.decimation) == ("aof", 0.005, 4)  # 'fast': 5 ms on every feet
    assert on_aof.policy_dt == pytest.approx(ball.policy_dt)
    fine = replace(envs.default_config("flat", "aof", "B", "fast"), sim_dt=0.0025, decimation=8)
    on_ball = envs.on_feet(fine, "ball")
    assert (on_ball.feet, on_ball.sim_dt, on_ball.decimation) == ("ball", 0.0025, 8)
    # A policy step the feet's step does not divide keeps the policy's own physics.
    odd = envs.on_feet(replace(ball, sim_dt=0.006, decimation=3), "aof")
    assert (odd.feet, odd.sim_dt, odd.decimation) == ("aof", 0.006, 3)
    # A stance policy gets the step and iterations the stance needs on the other feet (float64
    # AOF 16/16, where ball needs 8/16).
    stance = envs.with_float64_physics(envs.with_contact_model(ball, "stance"))
    assert (stance.solver_iterations, stance.solver_ls_iterations) == (8, 16)
    stance_on_aof = envs.on_feet(stance, "aof")
    assert (
        stance_on_aof.contact_model,
        stance_on_aof.solver_iterations,
        stance_on_aof.solver_ls_iterations,
        stance_on_aof.sim_dt,
        stance_on_aof.decimation,
    ) == ("stance", 16, 16, 0.0025, 8)
    built_configs = []
    monkeypatch.setattr("footforge.rl.policy_files.load_policy", lambda d: (None, ball, None))
    monkeypatch.setattr("footforge.envs.from_config", lambda c: built_configs.append(c) or c)
    evaluation._policy_and_env("policy", "aof", 1.0, None)
    assert (built_configs[0].feet, built_configs[0].sim_dt, built_configs[0].decimation) == ("aof", 0.005, 4)
    # Trained with a new command every 5 s (the flat default), evaluated on the common 10-s schedule.
    assert ball.commands.resample_s == pytest.approx(envs.FLAT_COMMAND_RESAMPLE_S) == pytest.approx(5.0)
    assert built_configs[0].commands.resample_s == pytest.approx(evaluation.EVALUATION_COMMAND_EVERY_S) == 10.0
    assert built_configs[0].commands.lin_vel_x_range == ball.commands.lin_vel_x_range  # its own ranges
    # Trained with a push every 5 s (a push curriculum) or none, evaluated under the task's default
    # pushes (every 15 s, up to 1 m/s), which the flat default trains with.
    assert built_configs[0].pushes == ball.pushes == evaluation.EVALUATION_PUSHES
    for pushes in (replace(ball.pushes, interval_s=5.0, max_speed=1.5), replace(ball.pushes, enabled=False)):
        monkeypatch.setattr(
            "footforge.rl.policy_files.load_policy", lambda d, p=pushes: (None, replace(ball, pushes=p), None)
        )
        evaluation._policy_and_env("policy", "aof", 1.0, None)
        assert built_configs[-1].pushes == evaluation.EVALUATION_PUSHES
        assert (built_configs[-1].pushes.interval_s, built_configs[-1].pushes.max_speed) == (15.0, 1.0)
        assert built_configs[-1].pushes.enabled


def test_the_flat_task_changes_commands_every_5_s_and_the_rough_task_every_10_s():
    assert envs.default_config("flat", "aof", "B").commands.resample_s == pytest.approx(5.0)
    assert envs.default_config("rough", "aof", "PH").commands.resample_s == pytest.approx(10.0)  # legged_gym's


def test_the_warp_backend_is_refused_where_it_cannot_run(built, tmp_path, capsys, monkeypatch):
    """EnvConfig.mjx_impl 'warp' needs MuJoCo Warp and an NVIDIA GPU: without them the
    environment refuses it with the fix named, and training exits 2 before writing its run.
    MuJoCo Warp is hidden from the check, so the refusal is tested on any machine."""
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util,
        "find_spec",
        lambda name, *args: None if name in ("warp", "mujoco_warp") else find_spec(name, *args),
    )
    config = replace(envs.default_config("flat", "ball", "B"), build_dir=str(built["ball"][0]), mjx_impl="warp")
    with pytest.raises(InputError, match="warp") as e:
        envs.from_config(config)
    assert "jax" in e.value.fix
    from footforge.cli.train import main

    run = tmp_path / "run"
    code = main(
        "flat",
        "",
        [
            "--feet",
            "ball",
            "--build-root",
            str(built["ball"][0].parent),
            "--out",
            str(run),
            "--mjx-impl",
            "warp",
            "--timesteps",
            "100",
        ],
    )
    assert code == 2 and "mjx_impl 'warp'" in " ".join(capsys.readouterr().err.split())
    assert not run.exists()


def test_policy_types_swept_by_the_benchmarks():
    assert envs.policy_types("rough", "ball", ["B", "PH", "P"]) == ["B", "P"]  # PH stands for P on ball feet
    assert envs.policy_types("rough", "aof", ["B", "PH"]) == ["B", "PH"]
    assert envs.policy_types("flat", "aof", ["B", "PH"]) == ["B"]  # the flat task has blind policies only


def test_observation_noise_is_uniform_within_each_term_s_scale(built):
    """EnvConfig.observations.<term>.noise: each term's observation is its noiseless value plus
    uniform noise of +-noise in its unit, times its scale: never further than noise x scale from
    the noiseless observation, with the uniform's spread (noise x scale / sqrt(3)); terms of noise
    0, and every term with ObservationConfig.noise off, are the noiseless value exactly. A haptic
    policy on AOF feet (every noisy term), the C engine, one reset's state, 400 draws."""
    from footforge.envs import observation_layout

    config = replace(envs.default_config("flat", "aof", "BH"), build_dir=str(built["aof"][0]), physics="mujoco")
    noisy = envs.from_config(config)
    clean = envs.from_config(replace(config, observations=replace(config.observations, noise=False)))
    state = jax.jit(noisy.reset)(jax.random.PRNGKey(0))
    keys = jax.random.split(jax.random.PRNGKey(1), 400)
    observe = jax.jit(jax.vmap(noisy.observe, in_axes=(None, None, 0)))
    drawn = np.asarray(observe(state.pipeline_state, state.info, keys))
    observe_clean = jax.jit(clean.observe)
    truth = np.asarray(observe_clean(state.pipeline_state, state.info, keys[0]))
    np.testing.assert_array_equal(np.asarray(observe_clean(state.pipeline_state, state.info, keys[1])), truth)
    assert np.abs(truth).max() < config.observations.clip  # nothing clipped: the bounds below hold as stated
    terms = dict(observation_layout.terms(config))
    start = 0
    for name, width in observation_layout.layout(config, n_passive=16):
        term = terms[name]
        error = drawn[:, start : start + width] - truth[start : start + width]
        start += width
        bound = term.noise * np.abs(np.broadcast_to(np.asarray(term.scale, dtype=float), (width,)))
        if term.noise == 0:
            assert np.all(error == 0), name
            continue
        assert np.all(np.abs(error) <= bound * (1 + 1e-5) + 1e-6), name
        spread = error.std(axis=0) / (bound / np.sqrt(3))
        assert np.all((spread > 0.85) & (spread < 1.15)), (name, spread)
    assert start == truth.size
