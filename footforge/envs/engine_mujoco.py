"""The `mujoco` engine (footforge.envs.engine): MuJoCo's C engine steps the whole batch of robots.

The jitted, vmapped task code reaches it through `jax.pure_callback(..., vmap_method=
"broadcast_all")`: under Brax's vmap (and its scan and pmap) one host call receives every robot of
the batch, and `mujoco.rollout.Rollout` (a persistent thread pool, one MjData per thread) steps
them `decimation` times on all threads. What the task reads comes from MJCF sensors that
`add_sensors` declares in the model (MuJoCo Playground's and mjlab's way of reading contacts):
the actuator forces, the feet's touchdown sites, the poses of the bodies that carry the base and
thigh probes, and per foot a contact sensor against the ground (the number of contacts and the
normal force of the strongest `FOOT_CONTACT_SLOTS`).

Precision: the C engine runs in float64. JAX carries the state in the task's precision (float32
unless EnvConfig.float64_physics), so qpos and qvel travel as two float32 parts, the rounded value
(what the task reads) and its remainder, which restore the float64 state exactly at the next step.
Between policy steps MuJoCo's solver warm start (qacc_warmstart), which `mujoco.rollout` neither
returns nor keeps per robot, is carried as the last physics step's acceleration, (qvel_last -
qvel_before) / dt: a starting guess only (the solve converges from any start to its tolerance), and
the same for every thread count, so results never depend on how many threads run.

Domain randomisation (EnvConfig.randomization): Brax steps robot i with its own MJX model `sys`
(DomainRandomizationVmapWrapper); the fields the configuration randomises
(randomization.randomized_fields) travel with the host call, and each robot is stepped with its own
copy of the MjModel carrying them (`mujoco.rollout` takes one model per robot). Each copy is the
whole model, a rough terrain's heightfield included, so memory grows with the robots: randomised rough
training on a CPU holds one terrain per robot.
"""

from __future__ import annotations

import copy
import os
import threading

import jax
import jax.numpy as jp
import mujoco
import numpy as np
from flax import struct
from mujoco import rollout

from footforge import constants as C

FOOT_CONTACT_SLOTS = 24
"""Contacts each foot's sensor reports (the strongest first): an AOF foot's two sole boxes make up
to 4 contacts each on a plane; on a heightfield MuJoCo makes one per terrain prism a geom reaches:
up to 6 a box (benchmarks/box_on_heightfield.py), one a sphere, two where it sits on a crease
between prisms, so an AOF foot's 12 heightfield spheres (EnvConfig.heightfield_soles) 12-24; a ball
foot one or two."""
THREADS_ENV = "FOOTFORGE_PHYSICS_THREADS"
"""Environment variable: threads of the C engine's pool (default: the CPUs this process may use).
Results do not depend on it."""


def _numpy(*arrays) -> list[np.ndarray]:
    """The host callbacks' arguments (jax.Arrays on the CPU) as NumPy arrays (views, no JAX work)."""
    return [np.asarray(a) for a in arrays]


@struct.dataclass
class MujocoState:
    """One robot's physics state under the C engine (a JAX pytree; batched by Brax's vmap)."""

    qpos: jax.Array
    """Generalised positions, rounded to the task's precision."""
    qvel: jax.Array
    qpos_rest: jax.Array
    """float64 qpos - qpos (what the rounding dropped), in the task's precision."""
    qvel_rest: jax.Array
    ctrl: jax.Array
    """PD targets of every actuator (model order), rad."""
    warmstart: jax.Array
    """The constraint solver's starting acceleration for the next physics step (module docstring)."""
    sensordata: jax.Array
    """The model's sensors at the last physics step's forward pass."""
    force_sensors: tuple[int, ...] = struct.field(pytree_node=False, default=None)
    """The actuatorfrc sensors' addresses in sensordata, model order (static)."""

    @property
    def actuator_force(self) -> jax.Array:
        """Actuator forces (model order), N m: the actuatorfrc sensors."""
        return self.sensordata[..., self.force_sensors]


def add_sensors(
    spec: mujoco.MjSpec,
    model: mujoco.MjModel,
    foot_geoms,
    floor_geom: int,
    probe_bodies,
    foot_sites,
    *,
    ground_bodies=(),
) -> None:
    """Declares in `spec` (whose compiled form is `model`) the sensors the C engine reads, named
    `footforge/...` after the model's own: actuatorfrc per actuator, framepos of each foot site,
    framepos and frame axes of each probe body, and per leg a contact sensor between its foot
    (the subtree of `<leg>_foot/` for the adaptive feet, the foot geom for the ball: `foot_geoms`, per
    leg LF, RF, LH, RH, the geom ids of its foot) and the floor.

    For the CPU runner (CpuRobots), whose base and thighs collide with the ground for real:
    `ground_bodies` (body ids) get a contact sensor each between the body's own geoms and the floor
    (the nearest contact's distance), and a model with equality constraints (the closed chain's
    loop closures and roll couplings) the sensors its residuals are read from (ClosureResiduals)."""
    mj = mujoco.mjtObj
    for a in range(model.nu):
        spec.add_sensor(
            name=f"footforge/{model.actuator(a).name}_force",
            type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
            objtype=mj.mjOBJ_ACTUATOR,
            objname=model.actuator(a).name,
        )
    for s in foot_sites:
        spec.add_sensor(
            name=f"footforge/{model.site(s).name}_pos",
            type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
            objtype=mj.mjOBJ_SITE,
            objname=model.site(s).name,
        )
    for b in probe_bodies:
        name = model.body(b).name
        for axis, kind in (
            ("pos", mujoco.mjtSensor.mjSENS_FRAMEPOS),
            ("x", mujoco.mjtSensor.mjSENS_FRAMEXAXIS),
            ("y", mujoco.mjtSensor.mjSENS_FRAMEYAXIS),
            ("z", mujoco.mjtSensor.mjSENS_FRAMEZAXIS),
        ):
            spec.add_sensor(name=f"footforge/{name}_{axis}", type=kind, objtype=mj.mjOBJ_XBODY, objname=name)
    floor = model.geom(floor_geom).name
    for leg, feet in zip(C.LEGS, foot_geoms):
        foot_body = f"{C.FOOT_MODEL_NAME.format(leg=leg)}/"
        if mujoco.mj_name2id(model, mj.mjOBJ_BODY, foot_body) >= 0:
            objtype, objname = mj.mjOBJ_XBODY, foot_body  # MJCF subtree1: every geom of the adaptive foot
        elif len(feet) == 1 and model.geom(feet[0]).name:
            objtype, objname = mj.mjOBJ_GEOM, model.geom(feet[0]).name  # the ball foot's sphere
        else:
            raise ValueError(f"leg {leg}: neither a foot body '{foot_body}' nor one named foot geom")
        # MJCF: <contact subtree1|geom1=... geom2="floor" data="found force" reduce="maxforce" num=...>;
        # intprm holds (data bits: found 1, force 2; reduce: maxforce 2; slots).
        sensor = spec.add_sensor(
            name=f"footforge/{leg}_foot_contact",
            type=mujoco.mjtSensor.mjSENS_CONTACT,
            objtype=objtype,
            objname=objname,
            reftype=mj.mjOBJ_GEOM,
            refname=floor,
        )
        sensor.intprm[:3] = [1 | 2, 2, FOOT_CONTACT_SLOTS]
    for b in ground_bodies:
        # <contact body1=... geom2="floor" data="found dist" reduce="mindist" num="1">
        sensor = spec.add_sensor(
            name=f"footforge/{model.body(b).name}_ground",
            type=mujoco.mjtSensor.mjSENS_CONTACT,
            objtype=mj.mjOBJ_BODY,
            objname=model.body(b).name,
            reftype=mj.mjOBJ_GEOM,
            refname=floor,
        )
        sensor.intprm[:3] = [1 | 8, 1, 1]
    for i in range(model.neq):
        for k, obj in enumerate((model.eq_obj1id[i], model.eq_obj2id[i])):
            if model.eq_type[i] == mujoco.mjtEq.mjEQ_CONNECT:
                if model.eq_objtype[i] != mj.mjOBJ_SITE:
                    raise ValueError(f"equality {i}: a connect between bodies; the closure sensors expect sites")
                spec.add_sensor(
                    name=f"footforge/eq{i}_anchor{k}",
                    type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                    objtype=mj.mjOBJ_SITE,
                    objname=model.site(obj).name,
                )
            elif model.eq_type[i] == mujoco.mjtEq.mjEQ_JOINT and obj >= 0:
                spec.add_sensor(
                    name=f"footforge/eq{i}_joint{k}",
                    type=mujoco.mjtSensor.mjSENS_JOINTPOS,
                    objtype=mj.mjOBJ_JOINT,
                    objname=model.joint(obj).name,
                )
            elif model.eq_type[i] != mujoco.mjtEq.mjEQ_JOINT:
                raise ValueError(
                    f"equality {i}: type {model.eq_type[i]} has no residual sensor (connect and joint only)"
                )


class ClosureResiduals:
    """The violation of each equality constraint, read from add_sensors' closure sensors: a connect's
    anchors apart (m; MuJoCo's three constraint rows are that offset), a joint coupling's
    q1 - q1_0 - polynomial(q2 - q2_0) (rad; MuJoCo's one row). Sensors are those of a physics step's
    forward pass, the state before its integration, as MuJoCo's constraint rows."""

    def __init__(self, model: mujoco.MjModel):
        self.connect = np.flatnonzero(model.eq_type == mujoco.mjtEq.mjEQ_CONNECT)
        self.coupling = np.flatnonzero(model.eq_type == mujoco.mjtEq.mjEQ_JOINT)
        self._anchors = np.array(
            [[_sensor(model, f"footforge/eq{i}_anchor{k}") for k in (0, 1)] for i in self.connect], int
        ).reshape(-1, 2, 3)
        self._joints = np.array([_sensor(model, f"footforge/eq{i}_joint0")[0] for i in self.coupling], int)
        self._second = np.array(
            [_sensor(model, f"footforge/eq{i}_joint1")[0] if model.eq_obj2id[i] >= 0 else -1 for i in self.coupling],
            int,
        )
        jnt_qpos0 = lambda j: model.qpos0[model.jnt_qposadr[j]] if j >= 0 else 0.0  # noqa: E731
        self._q0 = np.array([[jnt_qpos0(model.eq_obj1id[i]), jnt_qpos0(model.eq_obj2id[i])] for i in self.coupling])
        self._poly = model.eq_data[self.coupling, :5]

    def __call__(self, sensordata: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(closure gaps (..., connects), m; coupling errors (..., couplings), rad) of sensordata (..., nsensordata)."""
        a = sensordata[..., self._anchors]  # (..., connects, 2, 3)
        gaps = np.linalg.norm(a[..., 0, :] - a[..., 1, :], axis=-1)
        q1 = sensordata[..., self._joints] - self._q0[:, 0]
        q2 = np.where(self._second >= 0, sensordata[..., np.maximum(self._second, 0)] - self._q0[:, 1], 0.0)
        poly = sum(self._poly[:, p] * q2**p for p in range(5))
        return gaps, np.abs(q1 - poly)


def physics_threads() -> int:
    """Threads of the C engine's pool: FOOTFORGE_PHYSICS_THREADS, else the CPUs this process may use."""
    value = os.environ.get(THREADS_ENV)
    if value:
        try:
            threads = int(value)
        except ValueError:
            threads = 0
        if threads < 1:
            from footforge.errors import InputError

            raise InputError(
                f"{THREADS_ENV}={value!r} is not a positive whole number",
                fix=f"set {THREADS_ENV} to the number of threads, or unset it",
            )
        return threads
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def _sensor(model: mujoco.MjModel, name: str) -> np.ndarray:
    """The sensordata addresses of sensor `name`."""
    s = model.sensor(name)
    return np.arange(s.adr[0], s.adr[0] + s.dim[0])


FULL_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
"""The state rollouts start from and return: time, qpos, qvel (and activations, history, plugins)."""


class Rollouts:
    """MuJoCo's threaded batch stepping for the robots of one model: `mujoco.rollout`'s persistent
    pool (physics_threads() threads, one MjData each), one call at a time. The one place footforge
    steps robots on the CPU: the C engine's host call (MujocoPhysics) and the CPU runner of
    evaluation and play (CpuRobots)."""

    def __init__(self, model: mujoco.MjModel):
        self.threads = threads = physics_threads()
        self._pool = rollout.Rollout(nthread=threads if threads > 1 else 0)
        self._datas = [mujoco.MjData(model) for _ in range(threads)]
        self._lock = threading.Lock()
        """Under pmap over several devices each device calls back on its own thread; the pool and its
        MjData are shared."""
        self.nstate = mujoco.mj_stateSize(model, FULL_STATE)
        if mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME.value) != 1 or model.na:
            raise ValueError("the C engine expects a model without actuator activations")
        # FULLPHYSICS lays out time, qpos, qvel, ... (MuJoCo's mjtState order).
        self.qpos = slice(1, 1 + model.nq)
        self.qvel = slice(1 + model.nq, 1 + model.nq + model.nv)
        self.dt = float(model.opt.timestep)

    def step(
        self,
        models,
        state0: np.ndarray,
        ctrl: np.ndarray,
        nstep: int,
        warmstart: np.ndarray,
        xfrc: np.ndarray | None = None,
    ):
        """`nstep` physics steps of each robot from its full physics state `state0` (N, nstate) under
        controls `ctrl` (N, nu) held through the steps, with `models` (one MjModel, or one per robot)
        and the constraint solver's starting acceleration `warmstart` (N, nv); `xfrc` (N, nbody, 6):
        forces applied to the bodies (the viewer's mouse), held likewise.

        Returns (states (N, nstep, nstate), sensordata (N, nstep, nsensordata), the next call's
        warmstart (N, nv), blew_up (N,)). The warmstart is the last physics step's acceleration,
        (qvel_last - qvel_before) / dt (the module docstring). A simulation that blew up (a position,
        velocity or acceleration past mjMAXVAL) is reset by MuJoCo to the model's qpos0 and time 0,
        with a warning, and goes on: its clock gives it away (blew_up)."""
        n = len(state0)
        control = np.repeat(np.asarray(ctrl, np.float64)[:, None, :], nstep, axis=1)
        spec = mujoco.mjtState.mjSTATE_CTRL.value
        if xfrc is not None:
            forces = np.asarray(xfrc, np.float64).reshape(n, 1, -1)
            control = np.concatenate([control, np.repeat(forces, nstep, axis=1)], axis=2)
            spec |= mujoco.mjtState.mjSTATE_XFRC_APPLIED.value
        with self._lock:
            states, sensors = self._pool.rollout(
                models,
                self._datas,
                state0,
                control,
                control_spec=spec,
                nstep=nstep,
                initial_warmstart=np.asarray(warmstart, np.float64),
            )
        before = states[:, -2, self.qvel] if nstep > 1 else state0[:, self.qvel]
        warm = (states[:, -1, self.qvel] - before) / self.dt
        blew_up = np.abs(states[:, -1, 0] - state0[:, 0] - nstep * self.dt) > 0.5 * self.dt
        return states, sensors, warm, blew_up


class CpuRobots:
    """Robots of one CPU model stepped together by the C engine (Rollouts), outside JAX: the runner
    of the closed-chain evaluation (footforge.rl.evaluate_closed_chain) and of footforge play, on any
    feet, the 34-joint closed chain included. `robot` comes from anymal.load_robot(for_mjx=False):
    its base and thighs collide with the ground, and its engine_model carries the sensors read here
    (add_sensors with ground_bodies and, for the closed chain, its closure sensors).

    Each robot's full physics state (float64), PD targets, solver warm start and last sensors are
    kept here; `sync` writes a robot into an MjData for what reads MuJoCo's data (the foot IMUs, the
    viewer, rendering)."""

    def __init__(self, robot, num: int):
        m = self.model = robot.engine_model
        if m is None:
            raise ValueError("CpuRobots needs a robot from load_robot(for_mjx=False) (its engine_model)")
        self.robot = robot
        self._rollouts = Rollouts(m)
        self.state = np.zeros((num, self._rollouts.nstate))
        self.ctrl = np.zeros((num, m.nu))
        self.warmstart = np.zeros((num, m.nv))
        self.sensordata = np.zeros((num, m.nsensordata))
        self.blew_up = np.zeros(num, bool)
        self._scratch = mujoco.MjData(m)
        self._force = np.concatenate([_sensor(m, f"footforge/{m.actuator(a).name}_force") for a in range(m.nu)])
        self._feet = np.stack([_sensor(m, f"footforge/{leg}_foot_contact") for leg in C.LEGS])
        # add_sensors' ground contacts, footforge/<body>_ground: the base's, and each leg's thigh's.
        ground = {
            m.sensor(i).name[len("footforge/") : -len("_ground")]: _sensor(m, m.sensor(i).name)
            for i in range(m.nsensor)
            if m.sensor(i).name.startswith("footforge/") and m.sensor(i).name.endswith("_ground")
        }
        pick = lambda names: np.array([ground[b] for b in names if b in ground], int).reshape(-1, 2)  # noqa: E731
        self._base = pick([C.BASE_BODY])
        self._thighs = [pick([f"{leg}_THIGH"]) for leg in C.LEGS]
        if not (len(self._base) and all(len(t) for t in self._thighs)):
            raise ValueError("CpuRobots needs the base's and every thigh's ground contact sensors (add_sensors)")
        self.closure = ClosureResiduals(m) if m.neq else None

    @property
    def qpos(self) -> np.ndarray:
        return self.state[:, self._rollouts.qpos]

    @property
    def qvel(self) -> np.ndarray:
        return self.state[:, self._rollouts.qvel]

    def take(self, i: int, data: mujoco.MjData) -> None:
        """Robot i becomes `data`'s robot (after mj_forward: its state, controls and sensors), at rest
        for the solver (no warm start), as a freshly reset MjData steps."""
        mujoco.mj_getState(self.model, data, self.state[i], FULL_STATE)
        self.ctrl[i], self.sensordata[i], self.warmstart[i], self.blew_up[i] = data.ctrl, data.sensordata, 0.0, False

    def sync(self, i: int, data: mujoco.MjData | None = None) -> mujoco.MjData:
        """`data` (default: a scratch MjData) holding robot i's state and controls, forward-computed."""
        data = self._scratch if data is None else data
        mujoco.mj_setState(self.model, data, self.state[i], FULL_STATE)
        data.ctrl[:] = self.ctrl[i]
        mujoco.mj_forward(self.model, data)
        return data

    def step(
        self,
        targets: np.ndarray,
        nstep: int,
        which: np.ndarray | None = None,
        push: np.ndarray | None = None,
        xfrc: np.ndarray | None = None,
    ) -> np.ndarray:
        """`nstep` physics steps of the robots `which` (a mask; default all) with PD targets `targets`
        (N, 12, the robot's actuated joints in its actuator_ids order); `push` (N, 2) sets the
        base's planar velocity first where not NaN (the environment's push); `xfrc` (N, nbody, 6)
        body forces. Returns the stepped robots' sensors at every physics step (n, nstep, nsensordata)."""
        which = np.ones(len(self.state), bool) if which is None else np.asarray(which, bool)
        self.ctrl[:, self.robot.actuator_ids] = targets
        if push is not None:
            pushed = which & ~np.isnan(push[:, 0])
            self.state[pushed, self._rollouts.qvel.start : self._rollouts.qvel.start + 2] = push[pushed]
        states, sensors, warm, blew_up = self._rollouts.step(
            self.model,
            self.state[which],
            self.ctrl[which],
            nstep,
            self.warmstart[which],
            None if xfrc is None else np.asarray(xfrc)[which],
        )
        self.state[which], self.warmstart[which] = states[:, -1], warm
        self.sensordata[which], self.blew_up[which] = sensors[:, -1], blew_up
        return sensors

    def actuator_force(self) -> np.ndarray:
        """(N, nu) actuator forces in model order, N m (the last physics step's)."""
        return self.sensordata[:, self._force]

    def feet_on_ground(self) -> np.ndarray:
        """(N, 4) whether each foot (LF, RF, LH, RH) touches the ground (its contact sensor found one)."""
        found = self.sensordata[:, self._feet].reshape(len(self.state), 4, FOOT_CONTACT_SLOTS, 4)[..., 0]
        return (found > 0).any(axis=2)  # type: ignore[return-value]  # found is 3-D: an array

    def ground_contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """((N,) any base geom touches the ground, (N,) legs with a thigh geom touching it): a contact
        found at a negative distance (penetration)."""

        def touching(sensors):  # sensors (k, 2): found, dist addresses
            return ((self.sensordata[:, sensors[:, 0]] > 0) & (self.sensordata[:, sensors[:, 1]] < 0)).any(axis=1)

        knees = sum(touching(t).astype(int) for t in self._thighs)
        return touching(self._base), knees

    def diverged(self, max_speed: float) -> np.ndarray:
        """(N,) by the environment's criterion (EnvConfig.diverged_speed): a non-finite state, a
        generalised velocity past `max_speed`, or a simulation MuJoCo reset because it blew up."""
        finite = np.isfinite(self.state).all(axis=1)
        return ~finite | (np.abs(np.nan_to_num(self.qvel, nan=np.inf)) >= max_speed).any(axis=1) | self.blew_up


class MujocoPhysics:
    """MuJoCo's C engine behind footforge.envs.engine's interface (module docstring)."""

    name = "mujoco"

    def __init__(self, config, robot, probe_geoms, probe_local):
        from footforge.envs.randomization import randomized_fields

        m = self.model = robot.engine_model
        self._randomized = randomized_fields(config.randomization)
        """The model fields each robot brings from its own `sys` (module docstring)."""
        self._robot_models: list[mujoco.MjModel] = []
        self._written: list[np.ndarray] = []
        """The randomised fields' values last written into _robot_models, per field (batch, ...)."""
        self._decimation = config.decimation
        self._rollouts = Rollouts(m)
        self._forward_data = mujoco.MjData(m)
        self._lock = threading.Lock()
        """One host call at a time (under pmap each device calls back on its own thread): the
        per-robot models and the forward pass's MjData are shared."""
        self._nstate = self._rollouts.nstate
        self._qpos, self._qvel = self._rollouts.qpos, self._rollouts.qvel
        self._force_ids = tuple(
            int(i) for a in range(m.nu) for i in _sensor(m, f"footforge/{m.actuator(a).name}_force")
        )
        self._site_ids = jp.asarray(np.stack([_sensor(m, f"footforge/{m.site(s).name}_pos") for s in robot.foot_sites]))
        probe_geoms = np.asarray(probe_geoms)
        bodies = np.unique(m.geom_bodyid[probe_geoms])
        self._body_frames = jp.asarray(
            np.stack(
                [
                    np.concatenate(
                        [_sensor(m, f"footforge/{m.body(b).name}_{axis}") for axis in ("pos", "x", "y", "z")]
                    )
                    for b in bodies
                ]
            )
        )
        # Each probe point in its body's frame: the geom's pose in the body (geom_pos, geom_quat) applied.
        rotation = np.zeros((len(probe_geoms), 9))
        for i, g in enumerate(probe_geoms):
            mujoco.mju_quat2Mat(rotation[i], m.geom_quat[g])
        local = np.einsum("pij,pj->pi", rotation.reshape(-1, 3, 3), np.asarray(probe_local))
        self._probe_body = jp.asarray(np.searchsorted(bodies, m.geom_bodyid[probe_geoms]))
        self._probe_in_body = jp.asarray(m.geom_pos[probe_geoms] + local, jp.float32)
        self._contacts = jp.asarray(np.stack([_sensor(m, f"footforge/{leg}_foot_contact") for leg in C.LEGS]))

    # Host side -------------------------------------------------------------------------------
    def _initial_state(self, qpos, qpos_rest, qvel, qvel_rest) -> np.ndarray:
        state = np.zeros((len(qpos), self._nstate))
        state[:, self._qpos] = np.asarray(qpos, np.float64) + qpos_rest
        state[:, self._qvel] = np.asarray(qvel, np.float64) + qvel_rest
        return state

    def _models(self, robots: int, fields) -> mujoco.MjModel | list[mujoco.MjModel]:
        """The model of each of `robots` robots: the one model, or under domain randomisation a copy
        per robot carrying its randomised `fields` (arrays (batch..., *field shape), self._randomized
        order), written only where they changed (a robot's draw lasts the whole training). Called
        under the lock."""
        if not self._randomized:
            return self.model
        fields = [
            np.asarray(f, np.float64).reshape(robots, *getattr(self.model, name).shape)
            for name, f in zip(self._randomized, fields)
        ]
        if len(self._robot_models) != robots:
            self._robot_models = [copy.copy(self.model) for _ in range(robots)]
            self._written = []
        if not (self._written and all(np.array_equal(a, b) for a, b in zip(fields, self._written))):
            for name, values in zip(self._randomized, fields):
                for model, value in zip(self._robot_models, values):
                    getattr(model, name)[:] = value
            self._written = fields
        return self._robot_models

    def _host_step(self, qpos, qpos_rest, qvel, qvel_rest, ctrl, warmstart, *fields):
        # JAX hands a callback jax.Arrays: arithmetic on them would dispatch JAX work from inside the
        # computation that waits for this callback, which deadlocked under load (CI, 2026-11-28: a
        # `qpos + qpos_rest` here waited forever on XLA's CPU threads). NumPy views first, then only NumPy.
        qpos, qpos_rest, qvel, qvel_rest, ctrl, warmstart = _numpy(qpos, qpos_rest, qvel, qvel_rest, ctrl, warmstart)
        fields = _numpy(*fields)  # type: ignore[assignment]
        batch, dtype = qpos.shape[:-1], qpos.dtype
        flat = [np.reshape(x, (-1, x.shape[-1])) for x in (qpos, qpos_rest, qvel, qvel_rest, ctrl, warmstart)]
        qpos, qpos_rest, qvel, qvel_rest, ctrl, warmstart = flat
        state0 = self._initial_state(qpos, qpos_rest, qvel, qvel_rest)
        with self._lock:
            models = self._models(len(qpos), fields)
            states, sensors, warm, reset = self._rollouts.step(models, state0, ctrl, self._decimation, warmstart)
        last = states[:, -1]
        q64, v64 = last[:, self._qpos], last[:, self._qvel]
        # A simulation MuJoCo reset because it blew up (Rollouts.step) is handed back as NaN: it ends
        # the episode as a diverged one (LocomotionEnv.step's finiteness check), as under MJX, which
        # carries the NaNs.
        q64[reset], v64[reset] = np.nan, np.nan
        q, v = q64.astype(dtype), v64.astype(dtype)
        out = (q, (q64 - q).astype(dtype), v, (v64 - v).astype(dtype), warm.astype(dtype), sensors[:, -1].astype(dtype))
        return tuple(x.reshape(*batch, x.shape[-1]) for x in out)

    def _host_forward(self, qpos, qpos_rest, qvel, qvel_rest, ctrl, *fields):
        qpos, qpos_rest, qvel, qvel_rest, ctrl = _numpy(qpos, qpos_rest, qvel, qvel_rest, ctrl)  # as _host_step
        fields = _numpy(*fields)  # type: ignore[assignment]
        batch, dtype = qpos.shape[:-1], qpos.dtype
        qpos, qpos_rest, qvel, qvel_rest, ctrl = [
            np.reshape(x, (-1, x.shape[-1])) for x in (qpos, qpos_rest, qvel, qvel_rest, ctrl)
        ]
        d = self._forward_data
        out = np.empty((len(qpos), self.model.nsensordata))
        state = self._initial_state(qpos, qpos_rest, qvel, qvel_rest)
        with self._lock:
            models = self._models(len(qpos), fields)
            for i in range(len(qpos)):
                d.qpos[:], d.qvel[:], d.ctrl[:] = state[i, self._qpos], state[i, self._qvel], ctrl[i]
                mujoco.mj_forward(models if isinstance(models, mujoco.MjModel) else models[i], d)
                out[i] = d.sensordata
        return out.astype(dtype).reshape(*batch, out.shape[-1])

    # JAX side ---------------------------------------------------------------------------------
    def _fields_of(self, sys) -> list:
        """The randomised model fields of this robot's `sys` (none without domain randomisation)."""
        return [getattr(sys, name) for name in self._randomized]

    def start(self, sys, qpos, qvel, ctrl):
        zeros = jp.zeros_like
        state = MujocoState(
            qpos=qpos,
            qvel=qvel,
            qpos_rest=zeros(qpos),
            qvel_rest=zeros(qvel),
            ctrl=ctrl,
            warmstart=zeros(qvel),
            sensordata=jp.zeros(self.model.nsensordata, qpos.dtype),
            force_sensors=self._force_ids,
        )
        return self.forward(sys, state)

    def place(self, state, qpos, qvel, ctrl, where=True):
        zeros = jp.zeros_like
        fields = {
            "qpos": qpos,
            "qvel": qvel,
            "ctrl": ctrl,
            "qpos_rest": zeros(state.qpos_rest),
            "qvel_rest": zeros(state.qvel_rest),
            "warmstart": zeros(state.warmstart),
        }
        return state.replace(**{k: jp.where(where, v, getattr(state, k)) for k, v in fields.items()})

    def forward(self, sys, state):
        shape = jax.ShapeDtypeStruct((self.model.nsensordata,), state.qpos.dtype)
        sensordata = jax.pure_callback(
            self._host_forward,
            shape,
            state.qpos,
            state.qpos_rest,
            state.qvel,
            state.qvel_rest,
            state.ctrl,
            *self._fields_of(sys),
            vmap_method="broadcast_all",
        )
        return state.replace(sensordata=sensordata)

    def step(self, sys, state, ctrl, qvel):
        pushed = qvel != state.qvel  # a changed velocity (a push) drops its float64 remainder
        qvel_rest = jp.where(pushed, 0.0, state.qvel_rest)
        like = lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype)  # noqa: E731
        shapes = (
            like(state.qpos),
            like(state.qpos),
            like(qvel),
            like(qvel),
            like(qvel),
            jax.ShapeDtypeStruct((self.model.nsensordata,), state.qpos.dtype),
        )
        qpos, qpos_rest, qvel, qvel_rest, warmstart, sensordata = jax.pure_callback(
            self._host_step,
            shapes,
            state.qpos,
            state.qpos_rest,
            qvel,
            qvel_rest,
            ctrl.astype(state.qpos.dtype),
            state.warmstart,
            *self._fields_of(sys),
            vmap_method="broadcast_all",
        )
        state = state.replace(
            qpos=qpos,
            qpos_rest=qpos_rest,
            qvel=qvel,
            qvel_rest=qvel_rest,
            ctrl=ctrl,
            warmstart=warmstart,
            sensordata=sensordata,
        )
        return state

    # What the task reads ---------------------------------------------------------------------------
    def _contact_slots(self, state):
        """(found (4, slots), normal force (4, slots)) of each foot's contact sensor."""
        slots = state.sensordata[self._contacts].reshape(4, FOOT_CONTACT_SLOTS, 4)
        return slots[..., 0], slots[..., 1]

    def foot_contacts(self, sys, state):
        found, _ = self._contact_slots(state)
        return jp.any(found > 0, axis=1)

    def foot_forces(self, sys, state):
        _, normal = self._contact_slots(state)
        return jp.sum(normal, axis=1)

    def probe_points(self, state):
        frames = state.sensordata[self._body_frames].reshape(-1, 4, 3)  # pos, x axis, y axis, z axis
        position, axes = frames[:, 0], frames[:, 1:]  # axes[b, k] = body axis k in the world
        body = self._probe_body
        return position[body] + jp.einsum("pkj,pk->pj", axes[body], self._probe_in_body)

    def foot_positions(self, state):
        return state.sensordata[self._site_ids]
