"""The paper's evaluation of a trained policy: many robots walking under random commands and
pushes, and the mean and standard deviation over all policy steps of its indices.

Indices, per policy step of every robot still standing: forward and lateral velocity tracking
errors |v_cmd - v| (m/s), yaw-rate tracking error (rad/s), action rate ||a_t - a_t-1|| (Euclidean
norm over the 12 joints of the change of the policy output), joint velocity rate
||qd_t - qd_t-1|| (rad/s per step), joint torques ||tau|| (N m), base height (m). Foot slippage
(Catalano et al. 2022): the summed horizontal displacement of every foot between two steps in
which it touches the ground, over the horizontal distance the base travelled. Falls, and among
them the robots whose simulation diverged (counted apart: a diverged robot's indices would be
NaN, and it is masked like a fall).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np

from footforge.envs.config import PushConfig, check_policy_on_feet
from footforge.errors import InputError
from footforge.rl.verdict import judge
from footforge.tables import markdown_table
from footforge.variants import FEET, foot_variant

INDICES = (
    "lin_vel_x_error",
    "lin_vel_y_error",
    "yaw_rate_error",
    "action_rate",
    "joint_vel_rate",
    "torques",
    "base_height",
)
INDEX_UNITS = {
    "lin_vel_x_error": "m/s",
    "lin_vel_y_error": "m/s",
    "yaw_rate_error": "rad/s",
    "action_rate": "-",
    "joint_vel_rate": "rad/s per step",
    "torques": "N m",
    "base_height": "m",
}
"""Unit of each index (action_rate: policy outputs, unitless)."""
SECONDS = {"flat": 60.0, "rough": 17.5}
"""The paper's evaluation length per task, s."""


EVALUATION_COMMAND_EVERY_S = 10.0
"""Evaluations draw a new command every 10 s (legged_gym's resampling, the schedule of every policy
trained before 2026-11-27), whatever schedule the policy trained with (the flat task's default is
5 s: footforge.envs.FLAT_COMMAND_RESAMPLE_S), so that falls and errors compare across policies.
Command ranges and physics stay the policy's own."""

EVALUATION_PUSHES = PushConfig()
"""Evaluations push every robot as the task's default does (a new planar base velocity up to 1 m/s
every 15 s: legged_gym's push_interval_s and max_push_vel_xy), whatever pushes the policy trained
with (a push curriculum, or none under the `forward` preset), for the same reason: falls after a
push compare across policies only under one schedule. The paper names "interspersed base random
pushes" without a schedule."""


def foot_slip(feet_xy_before, feet_xy, touching_before, touching):
    """One step's foot slip, m: the summed horizontal displacement of the feet that touch the
    ground at both ends of the step (Catalano et al. 2022's slippage numerator). `feet_xy*`: (feet,
    2) positions; `touching*`: (feet,) contact flags."""
    import jax.numpy as jp

    return jp.sum(jp.linalg.norm(feet_xy - feet_xy_before, axis=-1) * (touching & touching_before), axis=-1)


def slippage_index(slip, travel, alive) -> float:
    """The slippage index: the feet's slip summed over every step of every standing robot, over the
    horizontal distance their bases travelled in those steps (NaN where they did not travel).
    `slip`, `travel`, `alive`: (robots, steps)."""
    travel_m = float(np.where(alive, travel, 0.0).sum())  # a fallen robot's NaN x 0 would be NaN: select
    return float(np.where(alive, slip, 0.0).sum() / travel_m) if travel_m > 0 else float("nan")


def _policy_and_env(
    policy_dir: Path, feet: str | None, seconds: float | None, build_dir: str | None, physics: str = "auto"
):
    """(policy, its training EnvConfig, feet, seconds, an environment of `feet` whose episodes
    outlast `seconds`). `feet` defaults to the training feet (a haptic policy runs on those only),
    `seconds` to SECONDS of the policy's task, `physics` (footforge.envs.engine: auto, mjx or
    mujoco) to the CPU's C engine or a GPU's MJX, whichever engine the policy trained on.

    Raises:
      InputError: a haptic policy on other feet (or no policy in the folder).
    """
    from footforge.envs import enable_float64_physics, from_config, on_feet
    from footforge.rl.policy_files import load_policy

    policy, env_config, _ = load_policy(policy_dir)
    enable_float64_physics(env_config)  # the physics it trained on (EnvConfig.float64_physics)
    feet = feet or env_config.feet
    check_policy_on_feet(env_config, feet, str(policy_dir))
    seconds = seconds or SECONDS[env_config.task]
    config = on_feet(env_config, feet)
    # One schedule of new commands for every policy, whatever it trained with (EVALUATION_COMMAND_EVERY_S).
    # No standing commands either (CommandConfig.standing_fraction): every policy is judged walking.
    # One schedule of pushes too (EVALUATION_PUSHES).
    config = replace(
        config,
        commands=replace(config.commands, resample_s=EVALUATION_COMMAND_EVERY_S, standing_fraction=0.0),
        pushes=EVALUATION_PUSHES,
    )
    from footforge.envs import engine

    env = from_config(
        replace(config, build_dir=build_dir, episode_length_s=seconds + 1.0, physics=engine.resolve(physics))
    )
    return policy, env_config, feet, seconds, env


def evaluate(
    policy_dir: Path,
    *,
    feet: str | None = None,
    num_envs: int = 1024,
    seconds: float | None = None,
    seed: int = 0,
    build_dir: str | None = None,
    physics: str = "auto",
) -> dict:
    """Runs `policy_dir`'s policy on `feet` (default: the feet it was trained on) for `seconds`
    (default: SECONDS of its task).

    Returns {"indices": {name: {"mean", "std"}}, "slippage", "falls", "diverged", "traces": {...}}
    where "falls" counts the robots that fell, "diverged" those of them whose simulation diverged
    (a non-finite state or reward term: the environment's `diverged` metric), and the traces
    (robot 0's foot contacts, the mean base velocity error) feed the plots. Rough-terrain policies
    walk the terrain they trained on (its seed), the robots spread over the terrain kinds
    first, then the levels, then each kind's columns (spawn_tiles); "by_terrain" then holds each
    kind's and level's indices and falls, and "kinds_not_covered" the kinds that too few robots left
    out.

    Raises:
      InputError: a haptic policy on feet whose passive joints differ from its training feet.
    """
    import jax
    import jax.numpy as jp

    from footforge.rl.policy_files import policy_digest

    digest = policy_digest(policy_dir)  # of the files loaded next, before any later write could replace them
    policy, env_config, feet, seconds, env = _policy_and_env(policy_dir, feet, seconds, build_dir, physics)
    config, robot = env.config, env.robot
    steps = int(round(seconds / env_config.policy_dt))
    rough = config.task == "rough"
    levels, columns = spawn_tiles(num_envs, env.terrain.column_kinds if rough else ("flat",), config.terrain.num_levels)

    from footforge.envs import rewards as reward_module

    reward_terms = tuple(reward_module.terms(config.rewards))
    clip = config.rewards.clip_total_at_zero

    def one_step(carry, key):
        # The robots keep walking without resets; a fallen (or diverged) one is masked from then on.
        state, prev_qd, alive, feet_xy, base_xy, touched = carry
        action, _ = policy(state.obs, key)
        action = env.clip_action(action)
        last_action = state.info["last_action"]
        state = env.step(state, action)
        d, m = state.pipeline_state, state.metrics
        qd = d.qvel[robot.actuated_dof]
        touching = env.foot_contacts(d)
        xy, new_base_xy = env.foot_positions(d)[:, :2], d.qpos[:2]
        diverged = alive & (m["diverged"] > 0)  # the step that ends a standing robot's walk, if it diverged
        alive = alive & (state.done == 0)
        lin, _, _ = env.base_state(d)
        row = {
            "lin_vel_x_error": m["error/lin_vel_x_per_step"],
            "lin_vel_y_error": m["error/lin_vel_y_per_step"],
            "yaw_rate_error": m["error/yaw_rate_per_step"],
            "action_rate": jp.linalg.norm(action - last_action),
            "joint_vel_rate": jp.linalg.norm(qd - prev_qd),
            "torques": jp.linalg.norm(d.actuator_force),
            "base_height": m["base_height_m_per_step"],
            "alive": alive,
            "slip": foot_slip(feet_xy, xy, touched, touching),
            "travel": jp.linalg.norm(new_base_xy - base_xy),
            "base_xy": new_base_xy,
            "contacts": touching,
            "base_vx_error": state.info["command"][0] - lin[0],
            "diverged": diverged,
            "command_vx": state.info["command"][0],
            "vx": lin[0],
            "command_speed": jp.linalg.norm(state.info["command"][:2]),
            "command_xy": state.info["command"][:2],
            "heading_error": env.heading_error(state.info, d),
            # The summed reward before its clip at zero (RewardConfig.clip_total_at_zero).
            "clipped": clip & (sum(m[f"reward/{t}"] for t in reward_terms) < 0),
        }
        return (state, qd, alive, xy, new_base_xy, touching), row

    def rollout(key, level, column):
        k_reset, k_run = jax.random.split(key)
        state = env.reset_on_tile(k_reset, level, column) if rough else env.reset(k_reset)
        d = state.pipeline_state
        carry = (
            state,
            d.qvel[robot.actuated_dof],
            jp.array(True),
            env.foot_positions(d)[:, :2],
            d.qpos[:2],
            env.foot_contacts(d),
        )
        _, rows = jax.lax.scan(one_step, carry, jax.random.split(k_run, steps))
        return rows | {"start_xy": d.qpos[:2]}

    rows = jax.jit(jax.vmap(rollout))(jax.random.split(jax.random.PRNGKey(seed), num_envs), levels, columns)
    rows = jax.tree.map(np.asarray, rows)
    alive = rows["alive"]
    if rough:
        rows["reach_m"] = reach_m(rows["base_xy"], rows.pop("start_xy"), alive)
        rows["crossed"] = rows["reach_m"] >= config.curriculum.promote_fraction_of_tile * config.terrain.tile_size_m
    indices = {
        name: {"mean": float(rows[name][alive].mean()), "std": float(rows[name][alive].std())} for name in INDICES
    }
    slippage = slippage_index(rows["slip"], rows["travel"], alive)
    vx_error = np.where(alive, rows["base_vx_error"], np.nan)
    walking = judge(rows["contacts"], alive, rows["base_height"], rows["command_vx"], rows["vx"], rows["command_speed"])
    robot_kinds = np.array(env.terrain.column_kinds if rough else ("flat",))[columns]  # each robot's terrain kind
    gaits = _gait_traces(rows, robot_kinds, levels) if rough else {}  # the contact schedules per kind (GAIT_KINDS)
    falls = fall_times(alive, env_config.policy_dt)
    pushes = event_times(config.pushes.interval_s, config.policy_dt, steps) if config.pushes.enabled else []
    commands = event_times(config.commands.resample_s, config.policy_dt, steps)
    return {
        "policy": str(policy_dir),
        "policy_sha256": digest,  # what a later comparison may reuse this result for
        "trained_on": env_config.feet,
        "feet": feet,
        "policy_type": env_config.policy,
        "physics": config.physics,
        "num_envs": num_envs,
        "seconds": seconds,
        "seed": seed,
        "policy_dt_s": env_config.policy_dt,
        "push_interval_s": config.pushes.interval_s,
        "task": config.task,
        "indices": indices,
        "slippage": slippage,
        "falls": int((~alive[:, -1]).sum()),
        "fall_times_s": falls,
        "push_times_s": pushes,
        "falls_after_push": len(falls_after(falls, pushes)),
        "command_times_s": commands,
        "falls_after_command": len(falls_after(falls, commands)),
        "command_changes": command_changes(rows["command_xy"], rows["heading_error"], alive, env_config.policy_dt),
        "diverged": int(rows["diverged"].any(axis=1).sum()),
        "walking": walking.to_dict() | {"line": walking.line()},
        "clipped_fraction": float(rows["clipped"][alive].mean()) if alive.any() else float("nan"),
        **(
            {
                "by_terrain": _by_terrain(rows, env.terrain.column_kinds, levels, columns),
                "walking_by_terrain": _walking_by_terrain(rows, robot_kinds),
                "gait_by_terrain": {k: {n: v for n, v in g.items() if n != "contacts"} for k, g in gaits.items()},
                "crossed": int(rows["crossed"].sum()),
                "kinds_covered": sorted(set(robot_kinds)),
                "kinds_not_covered": sorted(set(env.terrain.column_kinds) - set(robot_kinds)),
            }
            if rough
            else {}
        ),
        "traces": {
            "contacts_robot0": rows["contacts"][0],
            "base_vx_error_mean": _mean_over_standing(vx_error),
            **({"contacts_by_terrain": gaits} if rough else {}),
        },
    }


GAIT_KINDS = ("stairs_up", "stepping_stones")
"""The terrain kinds whose contact schedule a rough evaluation plots (the paper's Figures 11-14 show two
kinds; these two are also the ones `footforge evaluate --video` records): a climb and a gap-crossing."""
GAIT_WINDOW_S = 4.0
"""The contact schedules' length, s (the first seconds of the rollout)."""


def gait_robot(reach: np.ndarray, levels: np.ndarray, robot_kinds: np.ndarray, kind: str) -> int | None:
    """The robot whose contact schedule shows the gait on `kind`: of the robots on that kind's tiles, the one
    that got farthest from its start while up (`reach`, m: reach_m), the highest level among equals. A robot
    that stays up by standing on its spawn platform shows no gait; the one that went farthest walked the
    kind's obstacles most. None when no robot is on that kind."""
    on = np.flatnonzero(robot_kinds == kind)
    if on.size == 0:
        return None
    return int(on[np.lexsort((-on, levels[on], reach[on]))[-1]])  # the farthest, then the highest level


def _walking_by_terrain(rows: dict, robot_kinds: np.ndarray) -> dict:
    """{kind: the walking verdict (footforge.rl.verdict.judge) of the robots on that kind's tiles, as a dict
    with its "line"}."""
    out = {}
    for kind in sorted(set(robot_kinds)):
        v = _judge_robots(rows, robot_kinds == kind)
        out[str(kind)] = v.to_dict() | {"line": v.line()}
    return out


def _judge_robots(rows: dict, which):
    """footforge.rl.verdict.judge over the robots `which` (a mask or a slice of the rollout's rows)."""
    keys = ("contacts", "alive", "base_height", "command_vx", "vx", "command_speed")
    return judge(*(rows[k][which] for k in keys))


def _gait_traces(rows: dict, robot_kinds: np.ndarray, levels: np.ndarray) -> dict:
    """{kind: {"robot", "level", "reach_m", "up_steps", "steps", "gait", "contacts"}} for GAIT_KINDS
    (gait_robot's robot; its gait by footforge.rl.verdict over the whole rollout)."""
    out = {}
    steps = rows["alive"].shape[1]
    for kind in GAIT_KINDS:
        robot = gait_robot(rows["reach_m"], levels, robot_kinds, kind)
        if robot is None:
            continue
        v = _judge_robots(rows, slice(robot, robot + 1))
        out[kind] = {
            "robot": robot,
            "level": int(levels[robot]),
            "reach_m": round(float(rows["reach_m"][robot]), 2),
            "up_steps": int(rows["alive"][robot].sum()),
            "steps": int(steps),
            "gait": v.gait,
            "contacts": rows["contacts"][robot],
        }
    return out


AFTER_EVENT_S = 2.0
"""A fall this long after a push or a new command, or less, counts as that event's
(falls_after_push, falls_after_command), s: a base set moving at up to 1 m/s
(PushConfig.max_speed), or a new velocity and heading, is caught or not within a few strides."""


def fall_times(alive: np.ndarray, policy_dt: float) -> list[float]:
    """When each fallen robot fell, s from the start, sorted: the end of the first policy step after
    which it was down (`alive`: robots x policy steps, True while up)."""
    fell = ~alive[:, -1]
    first_down = np.argmin(alive[fell], axis=1)
    return sorted(round(float((i + 1) * policy_dt), 3) for i in first_down)


def event_times(every_s: float, policy_dt: float, steps: int) -> list[float]:
    """When an event every `every_s` seconds happens in a rollout of `steps` policy steps, s: policy
    step k has it when k is a multiple of the interval in steps (LocomotionEnv.push and
    next_command; every robot at the same steps, counted from its reset)."""
    every = max(1, round(every_s / policy_dt))
    return [round(k * policy_dt, 3) for k in range(every, steps + 1, every)]


def falls_after(falls: list[float], events: list[float], window_s: float = AFTER_EVENT_S) -> list[float]:
    """The fall times that come at most window_s after one of the events (its own step included)."""
    return [t for t in falls if any(0.0 <= t - e <= window_s + 1e-9 for e in events)]


SPEED_CHANGE_BINS_MPS = (0.0, 0.5, 1.0, 1.5, np.inf)
"""Bins of a new command's change of planar velocity, |v_new - v_old| (m/s): up to 2.2 m/s under commands of
+-1 / +-0.5 m/s, a reversal at full speed 2 m/s."""
TURN_BINS_RAD = (0.0, np.pi / 4, np.pi / 2, 3 * np.pi / 4, np.pi + 1e-6)
"""Bins of the turn a new heading asks, |heading target - yaw| just after the change (rad)."""


def command_changes(
    command_xy: np.ndarray,
    heading_error: np.ndarray,
    alive: np.ndarray,
    policy_dt: float,
    window_s: float = AFTER_EVENT_S,
) -> dict:
    """Which new commands the robots fall after: every change of a robot's planar velocity command
    while it is up, binned by the change of velocity (SPEED_CHANGE_BINS_MPS) and by the turn the new
    heading asks (TURN_BINS_RAD), with how many of each bin's robots fell within `window_s` of it.

    `command_xy` (robots x steps x 2), the command after each policy step; `heading_error` (robots x
    steps), the turn left to the heading target; `alive` (robots x steps), up after each step. A change
    at step s (command s differs from command s-1, the robot up after steps s-1 and s: a robot that goes
    down restarts with a fresh command in that step) counts a fall at step f (the first step after which
    the robot is down) when s < f <= s + window_s / policy_dt: falls_after's window, but for a fall in the
    very step of the new command, which falls_after counts and this leaves out (the policy never saw
    that command), so `fell` may be below falls_after_command by such falls."""
    changed = np.zeros(alive.shape, bool)
    # Up before and after the change: a robot that falls restarts with a fresh command in the same step.
    changed[:, 1:] = np.any(command_xy[:, 1:] != command_xy[:, :-1], axis=-1) & alive[:, :-1] & alive[:, 1:]
    robot, step = np.nonzero(changed)
    down = ~alive[:, -1]
    first_down = np.argmin(alive, axis=1)  # meaningful where down
    window = int(round(window_s / policy_dt))
    fell = down[robot] & (first_down[robot] >= step) & (first_down[robot] <= step + window)
    speed_change = np.linalg.norm(command_xy[robot, step] - command_xy[robot, step - 1], axis=-1)
    turn = np.abs(heading_error[robot, step])

    def binned(values, edges):
        which = np.digitize(values, edges[1:-1])
        return (
            np.bincount(which, minlength=len(edges) - 1).tolist(),
            np.bincount(which[fell], minlength=len(edges) - 1).tolist(),
        )

    speed_changes, speed_falls = binned(speed_change, SPEED_CHANGE_BINS_MPS)
    turn_changes, turn_falls = binned(turn, TURN_BINS_RAD)
    return {
        "changes": int(len(step)),
        "fell_within_s": window_s,
        "fell": int(fell.sum()),
        "speed_change_from_mps": [float(e) for e in SPEED_CHANGE_BINS_MPS[:-1]],
        "speed_change_changes": speed_changes,
        "speed_change_falls": speed_falls,
        "turn_from_rad": [round(float(e), 4) for e in TURN_BINS_RAD[:-1]],
        "turn_changes": turn_changes,
        "turn_falls": turn_falls,
    }


def _mean_over_standing(values: np.ndarray) -> np.ndarray:
    """Per time step, the mean over the robots still up (NaN where every robot has fallen: no
    warning, as numpy's nanmean would print when the policy is zero-shot on feet it falls on)."""
    up = np.isfinite(values)
    count = up.sum(axis=0)
    total = np.where(up, values, 0.0).sum(axis=0)
    return np.divide(total, count, out=np.full(total.shape, np.nan), where=count > 0)


def spawn_tiles(num_robots: int, column_kinds, num_levels: int) -> tuple[np.ndarray, np.ndarray]:
    """(level, column) of each robot's start tile: robot i goes to kind i mod K of the K kinds the
    terrain has (in the order of its columns), then, among that kind's robots, the j-th to level
    j mod num_levels of the kind's column (j // num_levels) mod its columns. A few robots thus
    cover every kind first (8 robots: 6 kinds, 2 of them twice) instead of one kind's levels."""
    kinds = list(dict.fromkeys(column_kinds))
    kind_columns = {k: [c for c, kind in enumerate(column_kinds) if kind == k] for k in kinds}
    levels, columns = np.zeros(num_robots, int), np.zeros(num_robots, int)
    for i in range(num_robots):
        kind, j = kinds[i % len(kinds)], i // len(kinds)
        levels[i] = j % num_levels
        columns[i] = kind_columns[kind][(j // num_levels) % len(kind_columns[kind])]
    return levels, columns


def crossed_tile(base_xy: np.ndarray, start_xy: np.ndarray, alive: np.ndarray, edge_m: float) -> np.ndarray:
    """Per robot, whether its base got `edge_m` or farther from where it started, in the plane, while it was
    up: the terrain curriculum's promotion rule (distance > promote_fraction_of_tile x tile side, half a tile:
    from the tile's centre to its edge), applied to an evaluation's walk instead of a training episode's end.

    base_xy: (robots, steps, 2) base positions, m; start_xy: (robots, 2), m; alive: (robots, steps)."""
    return reach_m(base_xy, start_xy, alive) >= edge_m


def reach_m(base_xy: np.ndarray, start_xy: np.ndarray, alive: np.ndarray) -> np.ndarray:
    """Per robot, the farthest its base got from where it started, in the plane, while it was up, m (0 for a
    robot down from its first step). Arguments as crossed_tile's."""
    distance = np.linalg.norm(base_xy - start_xy[:, None, :], axis=-1)
    return np.where(alive, distance, 0.0).max(axis=1)


def _by_terrain(rows: dict, column_kinds, levels: np.ndarray, columns: np.ndarray) -> dict:
    """{kind: {level: {"robots", "falls", "diverged", "crossed", index: mean over the standing steps}}}:
    "crossed", the robots that reached their tile's edge while up (crossed_tile)."""
    out: dict = {}
    kinds = np.array(column_kinds)[columns]
    for kind in sorted(set(kinds)):
        for level in sorted(set(levels[kinds == kind])):
            robots = (kinds == kind) & (levels == level)
            alive = rows["alive"][robots]
            cell: dict[str, float] = {
                "robots": int(robots.sum()),
                "falls": int((~alive[:, -1]).sum()),
                "diverged": int(rows["diverged"][robots].any(axis=1).sum()),
                "crossed": int(rows["crossed"][robots].sum()),
            }
            cell |= {name: float(rows[name][robots][alive].mean()) if alive.any() else float("nan") for name in INDICES}
            out.setdefault(kind, {})[int(level)] = cell
    return out


def terrain_markdown(results: list[dict]) -> str:
    """Rough-terrain results side by side (the paper's Figure 9 as a table): per terrain kind, the
    forward tracking error (m/s) over every level, the robots that crossed their tile and those that fell;
    then each kind's walking verdict."""
    rough = [r for r in results if r.get("by_terrain")]
    if not rough:
        return ""
    kinds = sorted({k for r in rough for k in r["by_terrain"]})
    head = ["policy", "type", "trained on", "feet", *[f"{k}: vx error / crossed / fell" for k in kinds]]
    rows = []
    for r in rough:
        cells = [Path(r["policy"]).parent.name or r["policy"], r["policy_type"], r["trained_on"], r["feet"]]
        for kind in kinds:
            tiles = r["by_terrain"].get(kind, {}).values()
            robots = sum(t["robots"] for t in tiles)
            error = np.nanmean([t["lin_vel_x_error"] for t in tiles]) if tiles else float("nan")
            crossed = sum(t.get("crossed", 0) for t in tiles)  # evaluations from before it was counted: 0
            cells.append(f"{error:.3f} / {crossed}/{robots} / {sum(t['falls'] for t in tiles)}/{robots}")
        rows.append(cells)
    table = "\n".join(markdown_table(head, rows)) + "\n"
    judged = [r for r in rough if r.get("walking_by_terrain")]  # evaluations from before it was judged: none
    if not judged:
        return table
    head = ["policy", "feet", *kinds]
    rows = []
    for r in judged:
        cells = [Path(r["policy"]).parent.name or r["policy"], r["feet"]]
        for kind in kinds:
            v = r["walking_by_terrain"].get(kind)
            cells.append(
                f"{v['verdict']}"
                + (f" ({v['gait']})" if v["verdict"] == "walks" else "")
                + f": up {v['uptime']:.0%}, vx error {v['forward_error_mps']:.2f}"
                if v
                else "-"
            )
        rows.append(cells)
    return (
        table
        + "\nWalking verdict per terrain kind (footforge/rl/verdict.py, over that kind's robots):\n\n"
        + ("\n".join(markdown_table(head, rows)) + "\n")
    )


def terrain_levels_markdown(result: dict) -> str:
    """One rough evaluation's robots by terrain kind (rows) and level (columns): in each cell the robots that
    crossed their tile and those that fell, of the robots spawned there ("crossed/robots, fell n"; a robot that
    crossed and then fell counts in both; "-/robots" in an evaluation from before crossings were counted);
    empty for a flat evaluation."""
    by_terrain = result.get("by_terrain") or {}
    levels = sorted({int(level) for tiles in by_terrain.values() for level in tiles})
    rows = []
    for kind in sorted(by_terrain):
        tiles = {int(level): t for level, t in by_terrain[kind].items()}
        rows.append(
            [kind]
            + [
                f"{tiles[lv].get('crossed', '-')}/{tiles[lv]['robots']}, fell {tiles[lv]['falls']}"
                if lv in tiles
                else "-"
                for lv in levels
            ]
        )
    return "\n".join(markdown_table(["kind", *(f"level {lv}" for lv in levels)], rows)) + "\n" if rows else ""


def record(
    policy_dir: Path,
    *,
    feet: str | None = None,
    seconds: float = 5.0,
    seed: int = 0,
    build_dir: str | None = None,
    kind: str | None = None,
    forward_mps: float = 0.6,
    physics: str = "auto",
) -> tuple[mujoco.MjModel, np.ndarray]:
    """One robot walking `seconds` under the policy (random commands and pushes; after a fall the
    environment restarts it), for footforge.rl.render: (the environment's CPU MjModel, qpos after
    every policy step (T, nq)). A rough-terrain policy with a terrain `kind` instead starts on the
    middle level's tile of that kind and is commanded straight ahead at `forward_mps`.

    Raises:
      InputError: as evaluate(), or a kind that the policy's terrain lacks.
    """
    import jax

    policy, env_config, feet, seconds, env = _policy_and_env(policy_dir, feet, seconds, build_dir, physics)
    steps = int(round(seconds / env_config.policy_dt))
    if kind is not None and (env_config.task != "rough" or kind not in env.terrain.column_kinds):
        raise InputError(
            f"the policy's terrain has no '{kind}' tiles",
            fix="record a kind of the rough terrain's proportions, or none on flat ground",
        )

    def reset(key):
        if kind is None:
            return env.reset(key)
        return env.reset_on_tile(
            key, env_config.terrain.num_levels // 2, env.terrain.column_kinds.index(kind), forward_mps=forward_mps
        )

    def one_step(state, key):
        action, _ = policy(state.obs, key)
        state = env.step(state, action)
        return state, state.pipeline_state.qpos

    @jax.jit
    def rollout(key):
        k_reset, k_run = jax.random.split(key)
        _, qpos = jax.lax.scan(one_step, reset(k_reset), jax.random.split(k_run, steps))
        return qpos

    return env.robot.model, np.asarray(rollout(jax.random.PRNGKey(seed)))


def comparison_markdown(results: list[dict]) -> str:
    """One row per (policy, feet): every index as mean +- std (the paper's Figure 8 as a table)."""
    head = ["policy", "type", "trained on", "feet", *INDICES, "slippage", "falls", "verdict"]
    rows = []
    for r in results:
        cells = [Path(r["policy"]).parent.name or r["policy"], r["policy_type"], r["trained_on"], r["feet"]]
        cells += [f"{r['indices'][k]['mean']:.3f} ± {r['indices'][k]['std']:.3f}" for k in INDICES]
        cells += [f"{r['slippage']:.3f}", falls_cell(r), r["walking"]["line"] if "walking" in r else "not judged"]
        rows.append(cells)
    return "\n".join(markdown_table(head, rows)) + "\n"


def falls_cell(r: dict) -> str:
    """'fallen/robots', with how many diverged and how many fell within AFTER_EVENT_S of a push or
    of a new command (results written before fall times were recorded have only the count)."""
    notes = [f"{r['diverged']} diverged"] if r.get("diverged") else []
    if r.get("falls") and "fall_times_s" in r:
        after = [f"{r['falls_after_push']} a push"] if r.get("push_times_s") else []
        after += [f"{r['falls_after_command']} a new command"] if r.get("command_times_s") else []
        if after:
            notes.append(f"within {AFTER_EVENT_S:g} s of: " + ", ".join(after))
    return f"{r['falls']}/{r['num_envs']}" + (f" ({', '.join(notes)})" if notes else "")


def command_falls_cell(r: dict) -> str:
    """'fell/changes' per bin of the new commands' change of velocity (command_changes), e.g.
    '<0.5 m/s 0/40, 0.5-1 1/60, 1-1.5 2/50, >=1.5 4/20'; '-' for results from before it was recorded."""
    c = r.get("command_changes")
    if not c:
        return "-"
    edges = c["speed_change_from_mps"]
    names = [f"<{edges[1]:g} m/s"] + [f"{a:g}-{b:g}" for a, b in zip(edges[1:-1], edges[2:])] + [f">={edges[-1]:g}"]
    return ", ".join(f"{n} {f}/{k}" for n, f, k in zip(names, c["speed_change_falls"], c["speed_change_changes"]))


FEET_COLOURS = {f: foot_variant(f).colour for f in FEET}
"""Each feet's colour in the comparison plot (footforge.variants)."""


def pair_label(r: dict) -> str:
    """A result's label in the plots: its run folder's name, then the feet walked on."""
    return f"{Path(r['policy']).parent.name}\non {r['feet']}"


def _plot_contacts(contacts, dt: float, title: str, path: Path) -> None:
    """One robot's feet contact schedule over its first GAIT_WINDOW_S: a black bar while a foot is on the
    ground."""
    from matplotlib.figure import Figure

    contacts = np.asarray(contacts)[: int(GAIT_WINDOW_S / dt)]
    fig = Figure(figsize=(8, 2.2))
    ax = fig.subplots()
    for leg in range(4):
        on = np.flatnonzero(contacts[:, leg])
        ax.broken_barh([(k * dt, dt) for k in on], (leg - 0.4, 0.8), color="k")
    ax.set(yticks=range(4), yticklabels=["LF", "RF", "LH", "RH"], xlabel="time (s)", title=title)
    ax.title.set_fontsize(9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def plot(results: list[dict], out_dir: Path) -> list[str]:
    """comparison.png (plot_indices), contacts_<i>.png (robot 0's feet contact schedule over the
    first 4 s; on rough terrain also contacts_<i>_<kind>.png for GAIT_KINDS), push_response_<i>.png
    (mean forward velocity error over time; pushes at the environment's interval)."""
    from matplotlib.figure import Figure  # no pyplot: a library leaves the backend to its user

    files = plot_indices(results, out_dir)
    labels = [pair_label(r) for r in results]
    for i, r in enumerate(results):
        dt = r["policy_dt_s"]
        label = labels[i].replace(chr(10), " ")
        _plot_contacts(
            r["traces"]["contacts_robot0"], dt, f"feet contact schedule: {label}", out_dir / f"contacts_{i}.png"
        )
        for kind, trace in r["traces"].get("contacts_by_terrain", {}).items():
            title = (
                f"{label}, {kind.replace('_', ' ')} level {trace['level']} (robot {trace['robot']}: "
                f"{trace['reach_m']:.1f} m from its start, up {trace['up_steps'] * dt:.1f} of "
                f"{trace['steps'] * dt:.1f} s): {trace['gait']}"
            )
            _plot_contacts(trace["contacts"], dt, title, out_dir / f"contacts_{i}_{kind}.png")
            files.append(f"contacts_{i}_{kind}.png")
        err = np.asarray(r["traces"]["base_vx_error_mean"])
        fig = Figure(figsize=(8, 2.5))
        ax = fig.subplots()
        ax.plot(np.arange(len(err)) * dt, err)
        for t in np.arange(r["push_interval_s"], r["seconds"], r["push_interval_s"]):
            ax.axvline(t, color="r", ls="--", lw=0.8)
        ax.set(xlabel="time (s)", ylabel="mean vx command - vx (m/s)", title="push response (pushes: red)")
        fig.tight_layout()
        fig.savefig(out_dir / f"push_response_{i}.png", dpi=90)
        files += [f"contacts_{i}.png", f"push_response_{i}.png"]
    return files


def plot_indices(results: list[dict], out_dir: Path) -> list[str]:
    """comparison.png: each index's mean and standard deviation per policy and feet (the paper's
    Figure 8), from results with or without their traces."""
    from matplotlib.figure import Figure

    # One panel per index; with many (policy, feet) rows the panels widen and wrap (4 a row).
    cols = len(INDICES) if len(results) <= 4 else 4
    rows = -(-len(INDICES) // cols)
    panel_width = max(3.0, 0.3 * len(results) + 1.0)
    fig = Figure(figsize=(panel_width * cols, 3.6 * rows))
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    labels = [pair_label(r) for r in results]
    for ax, name in zip(axes, INDICES):
        for k, r in enumerate(results):  # coloured by the feet walked on; hatched when zero-shot
            ax.bar(
                k,
                r["indices"][name]["mean"],
                yerr=r["indices"][name]["std"],
                capsize=2,
                color=FEET_COLOURS.get(r["feet"], "tab:blue"),
                hatch="//" if r["feet"] != r["trained_on"] else None,
            )
        ax.set_title(f"{name} ({INDEX_UNITS[name]})", fontsize=9)
        ax.set_xticks(range(len(results)), labels, fontsize=6, rotation=90)
    for ax in axes[len(INDICES) :]:
        ax.set_visible(False)
    fig.tight_layout()
    fig.savefig(out_dir / "comparison.png", dpi=90)
    return ["comparison.png"]
