"""The physics seam of the environments: which engine steps the robots, behind one small interface.

Two engines step the same MjModel (footforge.envs.anymal.load_robot) for the same JAX task code:

- `mjx` (footforge.envs.engine_mjx): MuJoCo MJX, the physics in JAX, jitted and vmapped with the
  task. The engine of a GPU.
- `mujoco` (footforge.envs.engine_mujoco): MuJoCo's own C engine in float64, the whole batch of
  robots stepped by MuJoCo's threaded `mujoco.rollout` from inside the jitted step through
  `jax.pure_callback`. On a CPU it is 3-28 times faster than MJX on the same model
  (benchmarks/RESULTS.md, "Physics engines").

Outside JAX, the closed-chain evaluation and footforge play step their robots with the `mujoco`
engine's pool too (engine_mujoco.CpuRobots), on any feet, the 34-joint closed chain included.

`EnvConfig.physics` chooses; `resolve("auto")` is `mujoco` where JAX's default backend is the CPU
and `mjx` elsewhere (the `--physics` option of train, evaluate and play).

The interface (an engine's methods; `sys` is the environment's MJX model, which Brax's domain
randomisation swaps per robot, `state` the engine's own physics state):

- `start(sys, qpos, qvel, ctrl)`: a robot at (qpos, qvel) with PD targets ctrl, everything the
  task reads computed for it;
- `place(state, qpos, qvel, ctrl, where)`: a restart where `where` (the fields a restart sets;
  what the task reads is recomputed by the next step or by `forward`, in both engines);
- `step(sys, state, ctrl, qvel)`: `decimation` physics steps from `state` with its joint
  velocities replaced by `qvel` (a push) and PD targets ctrl;
- what the task reads: `state.qpos`, `state.qvel`, `state.ctrl`, `state.actuator_force`
  (actuator order of the model, N m), `foot_contacts(sys, state)` (LF, RF, LH, RH),
  `foot_forces(sys, state)` (each foot's normal ground force, N), `probe_points(state)` (the
  world positions of the points named at construction: the base and thigh probes) and
  `foot_positions(state)` (the feet's touchdown sites, world, m); `forward(sys, state)` recomputes
  them for a placed state.

Derived quantities (contacts, forces, frames, actuator forces) are those of the last physics
step's forward pass, before its integration, in both engines (MJX's step and MuJoCo's mj_step
compute them there): one physics step (2.5 ms) behind qpos and qvel.
"""

from __future__ import annotations

from typing import Literal

from footforge.errors import InputError

PhysicsName = Literal["mjx", "mujoco"]
"""EnvConfig.physics's choices, the library default first."""
CHOICES = ("auto", "mjx", "mujoco")
"""The --physics option's choices."""


def resolve(choice: str) -> PhysicsName:
    """A --physics choice as the engine that runs: `auto` is `mujoco` where JAX's default backend
    is the CPU (MuJoCo's C engine is several times faster there), `mjx` on a GPU or TPU."""
    if choice not in CHOICES:
        raise InputError(f"unknown physics '{choice}'", fix=f"use one of {', '.join(CHOICES)}")
    if choice != "auto":
        return choice  # type: ignore[return-value]
    import jax

    return "mujoco" if jax.default_backend() == "cpu" else "mjx"


def check(physics: str) -> None:
    """Raises InputError where the engine `physics` (a resolved EnvConfig.physics) cannot start, so
    that a command refuses before writing or compiling anything: the C engine's thread count
    (FOOTFORGE_PHYSICS_THREADS)."""
    if physics == "mujoco":
        from footforge.envs.engine_mujoco import physics_threads

        physics_threads()


def make(config, robot, probe_geoms, probe_local):
    """The engine EnvConfig.physics names, for `robot` (anymal.Robot) whose task reads the world
    positions of the points `probe_local` (P, 3) in the frames of geoms `probe_geoms` (P,)."""
    if config.physics == "mjx":
        from footforge.envs.engine_mjx import MjxPhysics

        return MjxPhysics(config, robot, probe_geoms, probe_local)
    if config.physics == "mujoco":
        from footforge.envs.engine_mujoco import MujocoPhysics

        return MujocoPhysics(config, robot, probe_geoms, probe_local)
    raise InputError(f"unknown physics '{config.physics}'", fix="set EnvConfig.physics to mjx or mujoco")


def describe(name: str) -> str:
    """One line naming the engine, for a run's first lines and a policy card."""
    if name == "mujoco":
        return "mujoco (MuJoCo's C engine, float64, threaded mujoco.rollout)"
    return "mjx (MuJoCo MJX in JAX)"
