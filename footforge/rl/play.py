"""A trained policy walking in CPU MuJoCo, run through its ONNX file: footforge play.

What is exported is what is seen: the policy acts through onnxruntime on the graph that
`footforge export` writes (footforge.rl.export_onnx.build_model: for a policy folder the graph is
built in memory, for an .onnx file the file is read), never through the JAX checkpoint. Everything
around the network is the closed-chain runner's (footforge.rl.evaluate_closed_chain.Controller): the
environment's observation (noise included, as in training and evaluation), its action clip and PD
targets, its termination contacts, for one robot stepped by MuJoCo's C engine
(footforge.envs.engine_mujoco.CpuRobots, the `mujoco` training engine's pool); the runner calls the policy
inside its jitted step, through jax.pure_callback.

The command (forward vx m/s, lateral vy m/s, yaw rate rad/s, in the base's heading frame as in
training) is the user's, fixed (headless) or from the keyboard (the viewer): the environment's
command draws and heading steering are replaced, its random pushes are off. A robot that falls
(base or `terminate_on_knees` thigh contact, or a diverged simulation) is put back at its start,
as an episode ends in training.

Feet: the policy's own (the environment's physics step and solver), or another of ball, aff, aof
and full (the 34-joint closed chain), stepped at its build's own physics (step, solver, contacts),
as footforge.rl.evaluate_closed_chain runs the closed chain. Only blind (B) and perceptive (P) policies walk on
feet they were not trained on: haptic ones (BH, PH) read the passive joints of their own feet, or
on the closed chain those joints' estimates (footforge.rl.foot_imu).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from footforge.errors import InputError
from footforge.variants import (
    PLAY_FEET as FEET,  # the training feet and the closed chain
    Variant,
)

if TYPE_CHECKING:
    from footforge.envs.config import EnvConfig

TOOL = "footforge play"
"""Written into play's outputs (the GIF's comment, the log's "tool"): files play may replace."""


@dataclass(frozen=True)
class PlayConfig:
    """Where and how a policy plays."""

    feet: str | None = None
    """ball, aff, aof or full (the closed chain); None: the feet the policy was trained on."""
    terrain: bool = False
    """Walk on the closed-chain runner's terrain tiles (footforge.rl.evaluate_closed_chain.TERRAIN_TILES: smooth
    slope, rough slope, stairs down, obstacles, generated as the rough task's terrain) instead of
    flat ground; the robot starts on the first tile (the smooth slope at difficulty 0.5)."""
    build_root: Path | None = None
    """Folder with one build per feet, <root>/<feet>/; None: build/<feet> (footforge play builds
    a missing one first; here a missing build is an input error)."""
    seed: int = 0
    """Seeds the observation noise (each restart after a fall takes the next seed)."""


@dataclass(frozen=True)
class OnnxPolicy:
    """An exported policy: its onnxruntime session, metadata and the environment configuration
    its observation is laid out by."""

    source: Path
    """The policy folder or the .onnx file it was read from."""
    session: Any
    """onnxruntime.InferenceSession of the graph (input "obs", output "actions")."""
    metadata: dict
    """The ONNX metadata_props, JSON-decoded (footforge.rl.export_onnx.METADATA_KEYS)."""
    config: EnvConfig
    """footforge.envs.config.EnvConfig: the policy folder's own, or for an .onnx file the task's
    default configuration with the file's action, physics step and observation settings."""

    def actions(self, obs: np.ndarray) -> np.ndarray:
        """The policy's actions (batch, 12) for raw observations (batch, obs size): the mode,
        unclipped (the runner clips it, as the environment does)."""
        return self.session.run(["actions"], {"obs": np.asarray(obs, np.float32)})[0]

    def jax_policy(self) -> Callable:
        """The policy as the runner calls it, obs, key -> (actions, extras), usable under jax.jit."""
        import jax
        import jax.numpy as jp

        size = len(self.metadata["joint_names"])

        def policy(obs, key):
            if isinstance(obs, dict):  # a privileged critic's observation: the policy reads "state"
                obs = obs["state"]
            shape = jax.ShapeDtypeStruct((obs.shape[0], size), jp.float32)
            return jax.pure_callback(self.actions, shape, obs.astype(jp.float32)), {}

        return policy


def load_policy(path: Path) -> OnnxPolicy:
    """A policy folder (exported in memory, as `footforge export` would write it) or an .onnx file
    footforge exported.

    Raises:
      InputError: the path does not exist, is neither a footforge policy folder nor an .onnx file,
        the file is not a footforge policy, or its observation layout is not this footforge's.
    """
    import onnx
    import onnxruntime

    from footforge.rl.export_onnx import METADATA_KEYS, build_model
    from footforge.rl.policy_files import load_policy_config

    path = Path(path)
    if not path.exists():
        raise InputError(
            "no such policy folder or file",
            file=str(path),
            fix="pass a policy/ folder of a training run or an .onnx file from footforge export",
        )
    if path.is_dir():
        config = load_policy_config(path)  # an InputError for a folder that is not a policy
        model = build_model(path)
    elif path.suffix.lower() == ".onnx":
        try:
            model = onnx.load(str(path))
        except Exception as e:  # protobuf's DecodeError, OSError...
            raise InputError(
                f"cannot be read as ONNX ({e.__class__.__name__})",
                file=str(path),
                fix="export the policy again: footforge export POLICY_DIR --out FILE.onnx",
            ) from None
        config = None
    else:
        raise InputError(
            "is neither a policy folder nor an .onnx file",
            file=str(path),
            fix="pass a policy/ folder of a training run or an .onnx file from footforge export",
        )
    props = {p.key: p.value for p in model.metadata_props}
    missing = [k for k in METADATA_KEYS if k not in props]
    if missing:
        raise InputError(
            f"not a footforge policy (metadata {', '.join(missing[:3])} missing)",
            file=str(path),
            fix="export the policy with footforge export POLICY_DIR",
        )
    try:
        metadata = {k: json.loads(props[k]) for k in METADATA_KEYS}
    except ValueError:
        raise InputError(
            "its footforge metadata is not JSON",
            file=str(path),
            fix="export the policy again with footforge export POLICY_DIR",
        ) from None
    if config is None:
        config = _config_from_metadata(metadata, path)
    try:
        session = onnxruntime.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"])
    except Exception as e:  # onnxruntime's own exception types
        raise InputError(
            f"onnxruntime cannot load it: {e}",
            file=str(path),
            fix="export the policy again with footforge export POLICY_DIR",
        ) from None
    return OnnxPolicy(path, session, metadata, config)


def _config_from_metadata(meta: dict, path: Path):
    """The EnvConfig an .onnx file's observation is laid out by: the task's default for its feet
    and policy type, with the file's action model, physics step and observation clip and noise.
    The file's layout (slices, widths, scales, height scan) must be the configuration's: a file
    from a run with other observation settings is refused, not misread."""
    from footforge import envs
    from footforge.envs import observation_layout

    config = envs.default_config(meta["task"], meta["feet"], meta["policy_type"])
    a, o = meta["action"], meta["observation"]
    config = replace(
        config,
        action=a["model"],
        action_scale=a["scale"],
        action_clip=a["clip"],
        sim_dt=meta["sim_dt_s"],
        decimation=meta["decimation"],
        observations=replace(
            config.observations,
            clip=o["clip"],
            noise=o["noise_in_training"],
            pd_targets=any(s["name"] == "pd_target" for s in o["layout"]),
        ),
    )
    ours = [
        (name, width, np.ravel(observation_layout.scale(config, name)).tolist())
        for name, width in observation_layout.layout(config, o["passive_foot_joints"])
    ]
    theirs = [(s["name"], s["size"], np.ravel(s["scale"]).tolist()) for s in o["layout"]]
    scan = o.get("height_scan")
    same_scan = scan is None or (
        scan["x_m"] == list(config.height_scan.x_m)
        and scan["y_m"] == list(config.height_scan.y_m)
        and scan["offset_m"] == config.observations.height_offset_m
        and scan["clip_m"] == config.observations.height_clip_m
    )
    if ours != theirs or not same_scan:
        raise InputError(
            f"its observation layout is not this footforge's default for a {meta['policy_type']} "
            f"policy on the {meta['task']} task",
            file=str(path),
            fix="play the policy folder itself (its footforge.json has the configuration)",
        )
    return config


def check_feet(policy: OnnxPolicy, feet: str | None) -> Variant:
    """The feet to walk on (default the policy's own).

    Raises:
      InputError: unknown feet, or a haptic policy on derived feet it was not trained on (on the
        closed chain it reads its passive joints' estimates, footforge.rl.foot_imu).
    """
    from footforge.envs.config import check_policy_on_feet

    feet = feet or policy.config.feet
    if feet not in FEET:
        raise InputError(f"unknown feet '{feet}'", fix=f"use one of {', '.join(FEET)}")
    check_policy_on_feet(policy.config, feet, str(policy.source))
    return feet


class Player:
    """One robot walking under a policy: `step(command)` runs one policy step (observation,
    action through ONNX, PD targets, the physics steps), `reset()` puts it back at its start."""

    def __init__(self, policy: OnnxPolicy, config: PlayConfig = PlayConfig()):
        import mujoco

        from footforge.envs.engine_mujoco import CpuRobots
        from footforge.rl.evaluate_closed_chain import (
            TERRAIN_TILES,
            Controller,
            cpu_robot,
            observed_robot,
            policy_environment,
        )
        from footforge.rl.foot_imu import FootImuEstimator

        feet = check_feet(policy, config.feet)
        # The user commands and pushes (the viewer's mouse); the environment's pushes are off.
        env_config = replace(policy.config, pushes=replace(policy.config.pushes, enabled=False))
        env, own = policy_environment(env_config, config.build_root, TERRAIN_TILES if config.terrain else None)
        self.terrain = getattr(env, "terrain", None)
        self.feet, self.policy, self.config = feet, policy, config
        self.robot = (
            own
            if feet == env_config.feet
            else cpu_robot(env_config, feet, config.build_root, self.terrain, own_physics=True)
        )
        self.robots = CpuRobots(self.robot, 1)  # the C engine's CPU runner, as the closed-chain evaluation
        self.model = self.robots.model
        self.data = mujoco.MjData(self.model)
        """What the viewer shows and perturbs (its mouse forces, xfrc_applied, act on the next step)."""
        self.policy_dt = env_config.policy_dt
        self.decimation = int(round(self.policy_dt / self.model.opt.timestep))
        limits = env_config.commands
        # The commands the policy was trained on; play keeps the user's within them.
        self.command_low = np.array([limits.lin_vel_x_range[0], limits.lin_vel_y_range[0], -limits.yaw_rate_limit])
        self.command_high = np.array([limits.lin_vel_x_range[1], limits.lin_vel_y_range[1], limits.yaw_rate_limit])
        # A haptic policy on the closed chain reads its passive joints' estimates (footforge.rl.foot_imu).
        self._imu = FootImuEstimator(self.model, own.passive_names) if policy.config.haptic and feet == "full" else None
        self._control = Controller(env, observed_robot(self.robot, self._imu), policy.jax_policy())
        self.resets = 0
        self.reset(np.zeros(3))

    def reset(self, command) -> None:
        """The robot at its start (standing, at rest), the policy's memory (last action) cleared."""
        from footforge.rl.evaluate_closed_chain import observed_states, place_at_start

        place_at_start(self.robot, self.data, self.terrain, 0)
        self.robots.take(0, self.data)
        self._info, self._obs = self._control.start(
            *observed_states(self.robots, self._imu), self.config.seed + self.resets, self._command(command)
        )
        self.resets += 1

    def warm_up(self) -> None:
        """Compiles the runner's jitted step (seconds) with one step, then restarts: so that a
        viewer does not freeze on its first frame and a timing holds the steady state."""
        self.step(np.zeros(3))
        self.reset(np.zeros(3))

    def _command(self, command) -> np.ndarray:
        return np.clip(np.asarray(command, float), self.command_low, self.command_high)[None]

    def step(self, command) -> dict:
        """One policy step under `command` (vx, vy, yaw rate; clipped to the training ranges).
        Returns {"fell", "base_height_m" (above the ground under the base), "vx", "vy", "yaw_rate"
        (base frame, m/s and rad/s), "command", "feet_on_ground" (LF, RF, LH, RH)}; after a fall
        the robot is back at its start."""
        from footforge.rl.evaluate_closed_chain import observed_states

        command = self._command(command)
        action, targets, _, _, self._info, keys = self._control.act(self._obs, self.robots.qpos, self._info)
        self.robots.step(targets, self.decimation, xfrc=self.data.xfrc_applied[None])
        fell = bool(self._control.fallen(self.robots)[0])
        feet = self.robots.feet_on_ground()[0].tolist()
        self._info, self._obs, row = self._control.settle(
            *observed_states(self.robots, self._imu), self._info, keys, action, self.robots.actuator_force(), command
        )
        self.robots.sync(0, self.data)
        record = {
            "fell": fell,
            "base_height_m": float(row["base_height"][0]),
            "vx": float(row["vx"][0]),
            "vy": float(row["vy"][0]),
            "yaw_rate": float(row["yaw_rate"][0]),
            "command": command[0].tolist(),
            "feet_on_ground": feet,
        }
        if fell:
            self.reset(command[0])
        return record


def play_headless(player: Player, *, seconds: float, command=(0.0, 0.0, 0.0)) -> dict:
    """Runs `player` (warmed up: Player.warm_up) for `seconds` under a fixed command. Returns
    {"steps", "policy_dt_s", "falls", "fall_times_s", "wall_s", "real_time_factor" (simulated over
    wall-clock seconds), "states": per policy step "time_s", "base_pos_m"
    (world, after the step), "base_height_m", "vx", "vy", "yaw_rate", "fell", "feet_on_ground"},
    "walking" (footforge.rl.verdict's verdict of the run, its "line" included; the robot counts as
    down from its first fall), and "qpos" (steps, nq) for rendering (not JSON)."""
    from footforge.rl.verdict import judge

    steps = int(round(seconds / player.policy_dt))
    qpos = np.empty((steps, player.model.nq))
    keys = ("base_height_m", "vx", "vy", "yaw_rate", "fell", "feet_on_ground")
    states: dict[str, list] = {k: [] for k in ("time_s", "base_pos_m", *keys)}
    start = time.perf_counter()
    for t in range(steps):
        record = player.step(command)
        qpos[t] = player.data.qpos
        states["time_s"].append((t + 1) * player.policy_dt)
        states["base_pos_m"].append(player.data.qpos[:3].tolist())
        for k in keys:
            states[k].append(record[k])
    wall = time.perf_counter() - start
    falls = [t for t, fell in zip(states["time_s"], states["fell"]) if fell]
    commanded = player._command(command)[0]
    walking = judge(
        np.array([states["feet_on_ground"]], bool),
        ~np.cumsum(states["fell"])[None].astype(bool),
        np.array([states["base_height_m"]]),
        np.full((1, steps), commanded[0]),
        np.array([states["vx"]]),
        np.full((1, steps), float(np.linalg.norm(commanded[:2]))),
    )
    return {
        "steps": steps,
        "policy_dt_s": player.policy_dt,
        "physics_steps_per_policy_step": player.decimation,
        "command": player._command(command)[0].tolist(),
        "falls": len(falls),
        "fall_times_s": falls,
        "wall_s": wall,
        "real_time_factor": steps * player.policy_dt / wall if wall > 0 else float("nan"),
        "states": states,
        "walking": walking.to_dict() | {"line": walking.line()},
        "qpos": qpos,
    }


# The viewer's keys (GLFW key codes, as mujoco.viewer's key_callback receives them): (code, key name,
# what it does, command index or None, change). The arrows and Page Up/Down act on the command;
# MuJoCo's viewer binds them only while paused (stepping through its history).
KEY_MAP = (
    (265, "Up", "forward velocity vx +0.1 m/s", 0, 0.1),
    (264, "Down", "forward velocity vx -0.1 m/s", 0, -0.1),
    (266, "Page Up", "lateral velocity vy +0.1 m/s (to the left)", 1, 0.1),
    (267, "Page Down", "lateral velocity vy -0.1 m/s (to the right)", 1, -0.1),
    (263, "Left", "yaw rate +0.1 rad/s (turn left)", 2, 0.1),
    (262, "Right", "yaw rate -0.1 rad/s (turn right)", 2, -0.1),
    (269, "End", "stop: all three commands to 0", None, 0.0),
    (268, "Home", "put the robot back at its start", None, 0.0),
)


def key_map_text() -> str:
    """The key map as printed at the viewer's start."""
    width = max(len(name) for _, name, *_ in KEY_MAP)
    return "\n".join(f"  {name:<{width}}  {what}" for _, name, what, *_ in KEY_MAP)


def apply_key(command: np.ndarray, keycode: int) -> tuple[np.ndarray, bool]:
    """(the command after key `keycode`, whether the robot is to be reset); unknown keys change
    nothing."""
    for code, name, _, index, change in KEY_MAP:
        if code != keycode:
            continue
        command = command.copy()
        if index is not None:
            command[index] = round(command[index] + change, 6)
        elif name == "End":
            command[:] = 0.0
        return command, name == "Home"
    return command, False


def play_interactive(player: Player, *, print_fn: Callable[[str], None] = print) -> None:
    """MuJoCo's viewer on the robot, in real time (or as fast as the physics goes), the command
    from the keyboard (KEY_MAP), until the window is closed.

    Raises:
      InputError: the viewer cannot open (no display, or macOS without mjpython).
    """
    import collections

    import mujoco
    import mujoco.viewer

    player.warm_up()  # before the window opens
    keys: collections.deque[int] = collections.deque()  # key_callback runs on the viewer's thread: hand the keys over
    try:
        viewer = mujoco.viewer.launch_passive(player.model, player.data, key_callback=keys.append)
    except Exception as e:  # GLFW without a display, mjpython on macOS...
        raise InputError(
            f"MuJoCo's viewer cannot open: {e}",
            fix="run on a machine with a display, or use --headless --video FILE.gif",
        ) from None
    command = np.zeros(3)
    with viewer:
        with viewer.lock():
            viewer.cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            viewer.cam.trackbodyid = player.model.jnt_bodyid[0]  # the free joint's body: the base
            viewer.cam.distance, viewer.cam.elevation = 2.5, -20.0
        while viewer.is_running():
            started = time.perf_counter()
            reset = False
            while keys:
                command, home = apply_key(command, keys.popleft())
                command = np.clip(command, player.command_low, player.command_high)
                reset |= home
                print_fn(
                    f"command: vx {command[0]:+.1f} m/s, vy {command[1]:+.1f} m/s, yaw rate {command[2]:+.1f} rad/s"
                )
            with viewer.lock():
                if reset:
                    player.reset(command)
                record = player.step(command)
            if record["fell"]:
                print_fn("fell: back at the start")
            viewer.sync()
            time.sleep(max(0.0, player.policy_dt - (time.perf_counter() - started)))
