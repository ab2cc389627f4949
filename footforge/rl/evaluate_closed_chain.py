"""Zero-shot evaluation on the closed chain: a policy trained on simplified feet (ball, AFF, AOF)
run with CPU MuJoCo on the 34-joint SoftFoot-Q, beside the same policy on the feet it was trained on.

One runner makes both columns: N independent robots with the same seeds, so the same commands,
pushes and observation noise draws. The jitted policy is called once per policy step for all
robots together; in between, the robots are stepped together by the C engine's CPU runner
(footforge.envs.engine_mujoco.CpuRobots: MuJoCo's threaded mujoco.rollout, the pool the `mujoco`
training engine steps with; contacts, actuator forces and closure residuals read from MJCF
sensors), each feet at its own physics step: the closed chain at its build's 0.25 ms with its
build's solver (80 steps per 20 ms policy step), the training feet at the environment's sim_dt and
solver settings (2.5 ms, 8 steps under the `stance` contact). What the
policy sees and how its action becomes PD targets are the MJX environment's: observations (the
height scan of P policies included), commands, base velocity and height come from its own
functions (LocomotionEnv's, RoughEnv's on terrain tiles) evaluated on the CPU state.

Reported per feet (indices as in footforge.rl.evaluate, over the policy steps of every standing
robot): forward, lateral and yaw-rate tracking errors, action rate, joint velocity rate, torques
and base height (mean, std); falls (base contact, `terminate_on_knees` thigh contacts, or a
diverged simulation) and when they happened; the walking verdict (footforge.rl.verdict, as
footforge evaluate judges a policy: forward error, time up, base height, each foot's stance); the
simulated and wall-clock time. For the closed
chain also its closure drift: MuJoCo's residual of every equality constraint at every physics
step (the loop closures: distance between the two anchors, m; the roll coupling back = -front:
rad), as the mean over time of the worst constraint and its maximum.

Blind (B) and perceptive (P) policies run on any feet. Haptic ones (BH, PH) read the passive
joints of the AFF or AOF feet they were trained on; on the closed chain they read those joints'
estimates from the foot's IMUs (footforge.rl.foot_imu), and on other derived feet they are refused.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from footforge.envs.anymal import Robot, ensure_built, load_robot
from footforge.envs.config import check_policy_on_feet
from footforge.envs.engine_mujoco import CpuRobots
from footforge.envs.terrain import Terrain, TerrainConfig
from footforge.errors import InputError
from footforge.rl.evaluate import INDICES
from footforge.rl.foot_imu import IMU_BODIES, FootImuEstimator
from footforge.rl.verdict import judge
from footforge.tables import markdown_table

FULL = "full"
TERRAIN_TILES = TerrainConfig(
    num_levels=2,
    num_columns=4,
    tile_size_m=4.0,
    platform_m=2.0,
    border_m=20.0,
    proportions=(1.0, 1.0, 0.0, 1.0, 1.0, 0.0),
)
""""A few terrain tiles": smooth slope, rough slope, stairs down, obstacles at difficulty 0 and 0.5;
robot i spawns on the centre of a tile of the hardest level (one kind after the other). The 20 m
border keeps a robot walking 10 s at the fastest command on the heightfield. The 2 m platform
holds the whole stance: its feet reach 0.55 m from the base, and on a 1 m platform the closed
chain's front feet spawned 15-19 mm into the smooth slope and diverged within 0.04 s."""


class _State(NamedTuple):
    """The part of MuJoCo's data the environment's observation and command functions read."""

    qpos: object
    qvel: object


def evaluate_closed_chain(
    policy_dir: Path,
    *,
    seconds: float = 10.0,
    num_robots: int = 4,
    seed: int = 0,
    build_root: Path | None = None,
    terrain_tiles: TerrainConfig | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> dict:
    """Runs `policy_dir`'s policy on the feet it was trained on and on the closed chain.

    build_root: folder with one build per feet, <root>/<feet>/ (default build/<feet>, which
    footforge evaluate-closed-chain builds first where missing; a missing build is an input
    error here).
    terrain_tiles: a terrain (e.g. TERRAIN_TILES) instead of flat ground.
    progress(feet, policy steps done, total) is called after every policy step.

    Returns {"policy", "policy_type", "trained_on", ..., "feet": {trained feet: column, "full":
    column}} with per column "indices" {name: {"mean", "std"}}, "falls", "fall_times_s", "walking"
    (the verdict's fields and its "line"), "finite",
    "closure" (None without equality constraints), "wall_s" (the column's wall-clock time, JAX
    compilation included), "real_time_factor" (simulated robot-seconds per second spent stepping
    MuJoCo) and "traces" (robot-by-step arrays for plots, NaN once a robot fell).

    Raises:
      InputError: non-positive seconds or robots, or a policy step that is not a
        whole number of the closed chain's physics steps.
    """
    from footforge.rl.policy_files import load_policy

    policy, config, _ = load_policy(policy_dir)
    check_policy_on_feet(config, FULL, str(policy_dir))  # any policy: haptic ones read the sensors' estimates
    if seconds <= 0 or num_robots < 1:
        raise InputError(f"seconds ({seconds}) and robots ({num_robots}) must be positive", fix="e.g. 10 s, 4 robots")
    env, trained = policy_environment(config, build_root, terrain_tiles)
    terrain = getattr(env, "terrain", None)
    full = cpu_robot(config, FULL, build_root, terrain, own_physics=True)
    steps = int(round(seconds / config.policy_dt))
    result = {
        "policy": str(policy_dir),
        "policy_type": config.policy,
        "trained_on": config.feet,
        "seconds": seconds,
        "num_robots": num_robots,
        "seed": seed,
        "policy_dt_s": config.policy_dt,
        "push_interval_s": config.pushes.interval_s if config.pushes.enabled else None,
        "terrain": None
        if terrain is None
        else {
            "config": asdict(terrain.config),
            "difficulty": terrain.config.difficulty(terrain.config.num_levels - 1),
            "robot_tiles": [terrain.column_kinds[i % terrain.config.num_columns] for i in range(num_robots)],
        },
        "feet": {},
    }
    imu = FootImuEstimator(full.model, trained.passive_names) if config.haptic else None
    result["passive_joints_on_full"] = (
        None
        if imu is None
        else {
            "estimated_from": "IMUs (footforge.rl.foot_imu)",
            "imu_bodies": list(IMU_BODIES),
            "joints": list(trained.passive_names),
        }
    )
    for feet, robot in ((config.feet, trained), (FULL, full)):
        result["feet"][feet] = run(
            env,
            robot,
            policy,
            steps=steps,
            num_robots=num_robots,
            seed=seed,
            terrain=terrain,
            progress=(lambda done, f=feet: progress(f, done, steps)) if progress else None,  # type: ignore[misc]
            imu=imu if feet == FULL else None,
        )
    return result


def policy_environment(config, build_root: Path | None = None, terrain_tiles: TerrainConfig | None = None):
    """(env, robot): the environment whose maths the CPU runner evaluates for a policy trained
    with `config` (flat ground: LocomotionEnv; on `terrain_tiles`: RoughEnv, its terrain height
    under the base and under the height scan; env.terrain is then the Terrain), and the policy's
    own feet as a CPU robot (cpu_robot) on that ground."""
    from footforge.envs import enable_float64_physics
    from footforge.envs.locomotion import LocomotionEnv
    from footforge.envs.rough import RoughEnv

    enable_float64_physics(config)  # a policy trained in float64 physics: its environment's maths need x64
    if terrain_tiles:
        env = RoughEnv(
            replace(config, task="rough", terrain=terrain_tiles, build_dir=_build_dir(config.feet, build_root))
        )
        return env, cpu_robot(config, config.feet, build_root, env.terrain)
    robot = cpu_robot(config, config.feet, build_root, None)
    return LocomotionEnv(
        replace(config, task="flat", build_dir=_build_dir(config.feet, build_root)), robot=robot
    ), robot


def _build_dir(feet: str, build_root: Path | None) -> str | None:
    """<build_root>/<feet>, or None: the environments' default, build/<feet>."""
    return str(Path(build_root) / feet) if build_root else None


def cpu_robot(
    config, feet: str, build_root: Path | None, terrain: Terrain | None, *, own_physics: bool = False
) -> Robot:
    """`feet`'s robot for the CPU: the environment's index tables, on `terrain` if given (its
    base and thighs colliding with the heightfield for real: MuJoCo on the CPU can, so falls are
    real contacts); physics at the environment's step and solver, or (own_physics) at the build's."""
    config = replace(config, feet=feet, build_dir=_build_dir(feet, build_root))
    if own_physics:
        o = mujoco.MjSpec.from_file(str(ensure_built(config) / "scene.xml")).option
        decimation = config.policy_dt / o.timestep
        if abs(decimation - round(decimation)) > 1e-9:
            raise InputError(
                f"the policy step {config.policy_dt} s is not a multiple of the {feet} model's {o.timestep} s step",
                file=str(ensure_built(config) / "robot.xml"),
                fix="rebuild the model",
            )
        config = replace(
            config,
            sim_dt=o.timestep,
            decimation=int(round(decimation)),
            solver_iterations=o.iterations,
            solver_ls_iterations=o.ls_iterations,
            contact_model="build",
        )
    return load_robot(config, terrain, for_mjx=False)


def run(
    env,
    robot: Robot,
    policy,
    *,
    steps: int,
    num_robots: int,
    seed: int,
    terrain: Terrain | None = None,
    progress: Callable[[int], None] | None = None,
    imu: FootImuEstimator | None = None,
) -> dict:
    """One column: `num_robots` robots on `robot`'s model for `steps` policy steps (see the module
    docstring), stepped together by the C engine's CPU runner (footforge.envs.engine_mujoco.CpuRobots).
    `env` is the policy's environment (LocomotionEnv on flat ground, RoughEnv on `terrain`), whose
    observation, command and base-height functions the robots go through. `imu`: a haptic policy's
    passive joints estimated on the closed chain (`robot`)."""
    config, model = env.config, robot.model
    decimation = int(round(config.policy_dt / model.opt.timestep))
    control = Controller(env, observed_robot(robot, imu), policy)
    robots = CpuRobots(robot, num_robots)
    data = mujoco.MjData(robots.model)
    for i in range(num_robots):
        place_at_start(robot, data, terrain, i)
        robots.take(i, data)
    info, obs = control.start(*observed_states(robots, imu), seed)
    alive = np.ones(num_robots, bool)
    ok = np.ones(num_robots, bool)
    fall_step = np.full(num_robots, -1)
    # (robots, steps) records; a robot's row stays NaN (not alive) from its fall on.
    rows = {k: np.full((num_robots, steps), np.nan) for k in (*INDICES, "vx", "vx_command", "vy_command")}
    live = np.zeros((num_robots, steps), bool)
    feet_down = np.zeros((num_robots, steps, 4), bool)  # each foot on the ground after the step
    worst = {k: np.full((num_robots, steps), np.nan) for k in ("closure_gap_m", "coupling_rad")}
    totals = {k: np.zeros(2) for k in worst}  # (sum over physics steps of the worst constraint, steps)
    physics_wall = 0.0
    t_start = time.perf_counter()
    for t in range(steps):
        if not alive.any():  # all fell: nothing left to simulate
            break
        action, targets, push_now, push, info, keys = control.act(obs, robots.qpos, info)
        t0 = time.perf_counter()
        # As the environment: a push sets the base's planar velocity, then the physics runs.
        sensors = robots.step(targets, decimation, which=alive, push=np.where(push_now[:, None], push, np.nan))
        physics_wall += time.perf_counter() - t0
        if robots.closure is not None:  # every physics step's residuals, the worst constraint of each
            for k, residual in zip(worst, robots.closure(sensors)):
                per_step = residual.max(axis=-1, initial=0.0)  # (alive robots, physics steps)
                worst[k][alive, t] = per_step.max(axis=1)
                totals[k] += (per_step.sum(), per_step.size)
        ok &= ~robots.diverged(config.diverged_speed) | ~alive
        fallen = control.fallen(robots)
        feet_down[:, t] = robots.feet_on_ground()
        info, obs, row = control.settle(*observed_states(robots, imu), info, keys, action, robots.actuator_force())
        fall_step[alive & fallen] = t
        alive &= ~fallen
        live[:, t] = alive  # like footforge.rl.evaluate: the step a robot falls on is not counted
        for k, record in rows.items():
            record[alive, t] = row[k][alive]
        if progress:
            progress(t + 1)
    wall = time.perf_counter() - t_start
    if progress:
        progress(steps)
    indices = {
        name: {
            "mean": float(rows[name][live].mean()) if live.any() else float("nan"),
            "std": float(rows[name][live].std()) if live.any() else float("nan"),
        }
        for name in INDICES
    }
    simulated = float(np.where(fall_step >= 0, fall_step + 1, steps).sum() * config.policy_dt)
    walking = judge(
        feet_down,
        live,
        rows["base_height"],
        rows["vx_command"],
        rows["vx"],
        np.hypot(rows["vx_command"], rows["vy_command"]),
    )
    traces = {"vx_m_s": rows["vx"], "vx_command_m_s": rows["vx_command"]}
    closure: dict[str, float] | None = None
    if robots.closure is not None:
        traces |= worst
        closure = {"num_closures": len(robots.closure.connect), "num_couplings": len(robots.closure.coupling)}
        for k, mean, peak in (
            ("closure_gap_m", "closure_gap_mean_m", "closure_gap_max_m"),
            ("coupling_rad", "coupling_mean_rad", "coupling_max_rad"),
        ):
            total, count = totals[k]
            closure |= {mean: float(total / count), peak: float(np.nanmax(worst[k]))}
    return {
        "timestep_s": model.opt.timestep,
        "physics_steps_per_policy_step": decimation,
        "indices": indices,
        "falls": int((fall_step >= 0).sum()),
        "fall_times_s": [float((s + 1) * config.policy_dt) if s >= 0 else None for s in fall_step],
        "diverged": int((~ok).sum()),
        "finite": bool(ok.all()),
        "walking": walking.to_dict() | {"line": walking.line()},
        "simulated_s": simulated,
        "wall_s": wall,
        "physics_wall_s": physics_wall,
        "real_time_factor": simulated / physics_wall if physics_wall > 0 else float("nan"),
        "closure": closure,
        "traces": traces,
    }


def observed_robot(robot: Robot, imu: FootImuEstimator | None) -> Robot:
    """`robot` as the policy's side reads it. With `imu` (a haptic policy on the closed chain)
    the passive joints' estimates travel as extra coordinates after qpos and qvel
    (observed_states), where the robot's index tables now point."""
    if imu is None:
        return robot
    model, n = robot.model, len(imu.names)
    return replace(
        robot,
        passive_qpos=np.arange(model.nq, model.nq + n),
        passive_dof=np.arange(model.nv, model.nv + n),
        passive_names=tuple(imu.names),
    )


def observed_states(robots: CpuRobots, imu: FootImuEstimator | None) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) of the robots, as observed_robot's tables index them."""
    qpos, qvel = robots.qpos.copy(), robots.qvel.copy()
    if imu is None:
        return qpos, qvel
    estimates = [imu(robots.sync(i)) for i in range(len(qpos))]
    return (
        np.concatenate([qpos, np.stack([e[0] for e in estimates])], axis=1),
        np.concatenate([qvel, np.stack([e[1] for e in estimates])], axis=1),
    )


def place_at_start(robot: Robot, data: mujoco.MjData, terrain: Terrain | None = None, i: int = 0) -> None:
    """Puts robot i where the runner starts it: standing at rest under the default PD targets, as
    the environment starts, at the origin or (on `terrain`) on the centre of a tile of its
    hardest level, column i modulo the columns. `data` may belong to robot.model or to its
    engine_model (the same joints and actuators, more sensors): its own model computes it."""
    mujoco.mj_resetData(data.model, data)
    data.qpos[:] = robot.stand_qpos
    if terrain is not None:
        data.qpos[:2] = _spawn(terrain, i)
        data.qpos[2] += terrain.height_at(*data.qpos[:2])
    data.ctrl[robot.actuator_ids] = robot.default_q
    mujoco.mj_forward(data.model, data)


def _spawn(terrain: Terrain, i: int) -> np.ndarray:
    """Robot i on the centre of a tile of the hardest level, one column (kind) after the other."""
    c = terrain.config
    return np.array(terrain.tile_center(c.num_levels - 1, i % c.num_columns), float)


class Controller:
    """The MJX environment's policy side (LocomotionEnv.policy_start, policy_act, policy_command,
    policy_observe) for a batch of CPU robots, jitted and vectorised, with the same random keys.

    start: the policy's side of env.reset for given states; act: the policy's action, its PD
    targets and the push; fallen: the environment's termination, from the CPU robots' sensors;
    settle: after the physics (commands, tracking errors, next observation). start and settle
    take an optional command per robot (vx m/s, vy m/s, yaw rate rad/s; footforge's play) that
    replaces the environment's drawn, heading-steered one where it is not NaN. The environment's
    functions read the robot only through its index tables, so they are bound here to `robot`,
    whose MJX model is never needed.
    """

    def __init__(self, env, robot: Robot, policy):
        import jax
        import jax.numpy as jp

        from footforge.envs.locomotion import reset_keys

        env = copy.copy(env)
        env.robot = robot  # ANYmal's joints (defaults, ranges) are the same on every feet
        config, r = env.config, robot

        def start(qpos, qvel, rng, command):  # the PD targets start at the defaults
            return env.policy_start(_State(qpos, qvel), {}, reset_keys(rng), jp.asarray(r.default_q), command)

        def act(obs, qpos, info):
            if config.privileged_critic:  # the policy reads "state" only; the critic's slice is not needed
                obs = {
                    "state": obs,
                    "privileged_state": jp.zeros((obs.shape[0], env.observation_size["privileged_state"][0])),
                }
            return jax.vmap(env.policy_act)(info, policy(obs, jax.random.PRNGKey(0))[0])

        def settle(qpos, qvel, info, keys, action, actuator_force, command):
            state = _State(qpos, qvel)
            info, _ = env.policy_command(info, state, keys, command)
            lin, ang, _ = env.base_state(state)
            qd, command = qvel[r.actuated_dof], info["command"]
            row = {
                "lin_vel_x_error": jp.abs(command[0] - lin[0]),
                "lin_vel_y_error": jp.abs(command[1] - lin[1]),
                "yaw_rate_error": jp.abs(command[2] - ang[2]),
                "action_rate": jp.linalg.norm(action - info["last_action"]),
                "joint_vel_rate": jp.linalg.norm(qd - info["last_joint_vel"]),
                "torques": jp.linalg.norm(actuator_force),
                "base_height": env.base_height(state),
                "vx": lin[0],
                "vx_command": command[0],
                "vy_command": command[1],
                "vy": lin[1],
                "yaw_rate": ang[2],
            }
            info, obs = env.policy_observe(state, info, keys, action)
            return info, obs, row

        self._start = jax.jit(jax.vmap(start))
        self._act = jax.jit(act)
        self._settle = jax.jit(jax.vmap(settle))
        self._config = config
        self._split = lambda seed, n: jax.random.split(jax.random.PRNGKey(seed), n)

    def start(self, qpos: np.ndarray, qvel: np.ndarray, seed: int, command: np.ndarray | None = None):
        """(info, observations) of robots in states (qpos, qvel), robot i seeded from `seed`;
        `command` (robots, 3): see the class docstring."""
        return self._start(qpos, qvel, self._split(seed, len(qpos)), _commands(command, len(qpos)))

    def act(self, obs, qpos: np.ndarray, info):
        """(actions, PD targets (robots, 12) in actuator order, push now, push velocity, info, keys)."""
        action, target, push_now, push, info, keys = self._act(obs, qpos, info)
        return action, np.asarray(target), np.asarray(push_now), np.asarray(push), info, keys

    def fallen(self, robots: CpuRobots) -> np.ndarray:
        """Per robot, the environment's termination after its last step: a base contact with the
        ground, `terminate_on_knees` legs with a thigh contact, or a diverged simulation."""
        base, knees = robots.ground_contacts()
        return base | (knees >= self._config.terminate_on_knees) | robots.diverged(self._config.diverged_speed)

    def settle(self, qpos, qvel, info, keys, action, actuator_force, command: np.ndarray | None = None):
        """(info, observations, index rows as numpy) after the physics of a policy step;
        `command` (robots, 3): see the class docstring."""
        info, obs, row = self._settle(qpos, qvel, info, keys, action, actuator_force, _commands(command, len(qpos)))
        return info, obs, {k: np.asarray(v) for k, v in row.items()}


def _commands(command: np.ndarray | None, robots: int) -> np.ndarray:
    """Commands (robots, 3) for Controller's jitted functions: NaN where the environment's own."""
    if command is None:
        return np.full((robots, 3), np.nan, np.float32)
    return np.broadcast_to(np.asarray(command, np.float32), (robots, 3))


def comparison_markdown(results: list[dict]) -> str:
    """One row per (policy, feet): the policy on its training feet, then on the closed chain."""
    head = [
        "policy",
        "type",
        "trained on",
        "feet",
        "vx error (m/s)",
        "vy error (m/s)",
        "yaw-rate error (rad/s)",
        "base height (m)",
        "falls",
        "verdict",
        "closure gap mean / max (mm)",
        "roll coupling max (mrad)",
        "finite",
        "real-time factor",
    ]
    rows = []
    for r in results:
        for feet, c in r["feet"].items():
            cells = [
                Path(r["policy"]).parent.name or r["policy"],
                r["policy_type"],
                r["trained_on"],
                f"{feet} ({'trained' if feet == r['trained_on'] else 'zero-shot'}"
                f"{', passive joints from its sensors' if feet == FULL and r.get('passive_joints_on_full') else ''})",
            ]
            cells += [
                f"{c['indices'][k]['mean']:.3f} ± {c['indices'][k]['std']:.3f}"
                for k in ("lin_vel_x_error", "lin_vel_y_error", "yaw_rate_error", "base_height")
            ]
            falls = [f"{t:.2f}" for t in c["fall_times_s"] if t is not None]
            cells.append(f"{c['falls']}/{r['num_robots']}" + (f" (at {', '.join(falls)} s)" if falls else ""))
            cells.append(c["walking"]["line"])
            eq = c["closure"]
            cells += [
                f"{eq['closure_gap_mean_m'] * 1e3:.4f} / {eq['closure_gap_max_m'] * 1e3:.4f}" if eq else "-",
                f"{eq['coupling_max_rad'] * 1e3:.3f}" if eq else "-",
                "yes" if c["finite"] else f"no ({c['diverged']} diverged)",
                f"{c['real_time_factor']:.2f}",
            ]
            rows.append(cells)
    return "\n".join(markdown_table(head, rows)) + "\n"


def plot(result: dict, path: Path) -> None:
    """Robot 0's forward velocity on both feet and its command over time (top), and the closed
    chain's worst closure gap per robot (bottom)."""
    from matplotlib.figure import Figure  # no pyplot: a library leaves the backend to its user

    dt = result["policy_dt_s"]
    fig = Figure(figsize=(9, 6))
    top, bottom = fig.subplots(2, 1, sharex=True)
    # The same seeds give both feet the same forward-velocity commands.
    command = result["feet"][result["trained_on"]]["traces"]["vx_command_m_s"][0]
    time_s = np.arange(1, len(command) + 1) * dt
    top.plot(time_s, command, "k--", lw=0.8, label="command")
    for feet, c in result["feet"].items():
        top.plot(time_s, c["traces"]["vx_m_s"][0], lw=1, label=f"on {feet}")
        if c["closure"]:
            gaps = c["traces"]["closure_gap_m"] * 1e3
            for i, g in enumerate(gaps):
                bottom.plot(time_s, g, lw=0.8, label=f"robot {i}")
    top.set(
        ylabel="forward velocity (m/s)",
        title=f"{Path(result['policy']).parent.name or result['policy']}: "
        f"{result['policy_type']} policy trained on {result['trained_on']}, robot 0",
    )
    top.legend(fontsize=7, ncol=2)
    bottom.set(xlabel="time (s)", ylabel="worst closure gap (mm)", title="closed chain: closure drift per policy step")
    bottom.legend(fontsize=7, ncol=4)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
