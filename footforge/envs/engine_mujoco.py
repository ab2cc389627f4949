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

FOOT_CONTACT_SLOTS = 8
"""Contacts each foot's sensor reports (the strongest first): an AOF or AFF foot's two sole boxes
make up to 4 contacts each on a plane, a ball foot one."""
THREADS_ENV = "FOOTFORGE_PHYSICS_THREADS"
"""Environment variable: threads of the C engine's pool (default: the CPUs this process may use).
Results do not depend on it."""


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
    force_sensors: jax.Array = struct.field(pytree_node=False, default=None)
    """The actuatorfrc sensors' addresses in sensordata, model order (static)."""

    @property
    def actuator_force(self) -> jax.Array:
        """Actuator forces (model order), N m: the actuatorfrc sensors."""
        return self.sensordata[..., self.force_sensors]


def add_sensors(spec: mujoco.MjSpec, model: mujoco.MjModel, foot_geoms, floor_geom: int, probe_bodies,
                foot_sites) -> None:
    """Declares in `spec` (whose compiled form is `model`) the sensors the C engine reads, named
    `footforge/...` after the model's own: actuatorfrc per actuator, framepos of each foot site,
    framepos and frame axes of each probe body, and per leg a contact sensor between its foot
    (the subtree of `<leg>_foot/` for the adaptive feet, the foot geom for the ball: `foot_geoms`, per
    leg LF, RF, LH, RH, the geom ids of its foot) and the floor."""
    mj = mujoco.mjtObj
    for a in range(model.nu):
        spec.add_sensor(name=f"footforge/{model.actuator(a).name}_force", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mj.mjOBJ_ACTUATOR, objname=model.actuator(a).name)
    for s in foot_sites:
        spec.add_sensor(name=f"footforge/{model.site(s).name}_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                        objtype=mj.mjOBJ_SITE, objname=model.site(s).name)
    for b in probe_bodies:
        name = model.body(b).name
        for axis, kind in (("pos", mujoco.mjtSensor.mjSENS_FRAMEPOS), ("x", mujoco.mjtSensor.mjSENS_FRAMEXAXIS),
                           ("y", mujoco.mjtSensor.mjSENS_FRAMEYAXIS), ("z", mujoco.mjtSensor.mjSENS_FRAMEZAXIS)):
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
        sensor = spec.add_sensor(name=f"footforge/{leg}_foot_contact", type=mujoco.mjtSensor.mjSENS_CONTACT,
                                 objtype=objtype, objname=objname, reftype=mj.mjOBJ_GEOM, refname=floor)
        sensor.intprm[:3] = [1 | 2, 2, FOOT_CONTACT_SLOTS]


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

            raise InputError(f"{THREADS_ENV}={value!r} is not a positive whole number",
                             fix=f"set {THREADS_ENV} to the number of threads, or unset it")
        return threads
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def _sensor(model: mujoco.MjModel, name: str) -> np.ndarray:
    """The sensordata addresses of sensor `name`."""
    s = model.sensor(name)
    return np.arange(s.adr[0], s.adr[0] + s.dim[0])


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
        self._dt = float(m.opt.timestep)
        self._threads = physics_threads()
        self._pool = rollout.Rollout(nthread=self._threads if self._threads > 1 else 0)
        self._datas = [mujoco.MjData(m) for _ in range(max(self._threads, 1))]
        self._forward_data = mujoco.MjData(m)
        self._lock = threading.Lock()
        """One host call at a time: under pmap over several devices each device calls back on its own
        thread, and the pool and its MjData are shared."""
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
        self._nstate = mujoco.mj_stateSize(m, full)
        # FULLPHYSICS lays out time, qpos, qvel, act, ... (MuJoCo's mjtState order).
        self._qpos = slice(1, 1 + m.nq)
        self._qvel = slice(1 + m.nq, 1 + m.nq + m.nv)
        if mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_TIME.value) != 1 or m.na:
            raise ValueError("the C engine expects a model without actuator activations")
        self._force_ids = tuple(int(i) for a in range(m.nu) for i in _sensor(m, f"footforge/{m.actuator(a).name}_force"))
        self._site_ids = jp.asarray(np.stack([_sensor(m, f"footforge/{m.site(s).name}_pos") for s in robot.foot_sites]))
        probe_geoms = np.asarray(probe_geoms)
        bodies = np.unique(m.geom_bodyid[probe_geoms])
        self._body_frames = jp.asarray(np.stack([np.concatenate([_sensor(m, f"footforge/{m.body(b).name}_{axis}")
                                                                 for axis in ("pos", "x", "y", "z")])
                                                 for b in bodies]))
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
        fields = [np.asarray(f, np.float64).reshape(robots, *getattr(self.model, name).shape)
                  for name, f in zip(self._randomized, fields)]
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
        batch, dtype = qpos.shape[:-1], qpos.dtype
        flat = [np.reshape(x, (-1, x.shape[-1])) for x in (qpos, qpos_rest, qvel, qvel_rest, ctrl, warmstart)]
        qpos, qpos_rest, qvel, qvel_rest, ctrl, warmstart = flat
        state0 = self._initial_state(qpos, qpos_rest, qvel, qvel_rest)
        control = np.repeat(np.asarray(ctrl, np.float64)[:, None, :], self._decimation, axis=1)
        with self._lock:
            models = self._models(len(qpos), fields)
            states, sensors = self._pool.rollout(models, self._datas, state0, control, nstep=self._decimation,
                                                 initial_warmstart=np.asarray(warmstart, np.float64))
        last = states[:, -1]
        before = states[:, -2, self._qvel] if self._decimation > 1 else state0[:, self._qvel]
        q64, v64 = last[:, self._qpos], last[:, self._qvel]
        # A simulation that blew up (a position, velocity or acceleration past mjMAXVAL) is reset by
        # MuJoCo to the model's qpos0 and time 0, with a warning, and goes on; MJX would carry NaNs.
        # Its time gives it away: handed back as NaN, it ends the episode as a diverged one
        # (LocomotionEnv.step's finiteness check), as under MJX.
        reset = np.abs(last[:, 0] - self._decimation * self._dt) > 0.5 * self._dt
        q64[reset], v64[reset] = np.nan, np.nan
        q, v = q64.astype(dtype), v64.astype(dtype)
        out = (q, (q64 - q).astype(dtype), v, (v64 - v).astype(dtype),
               ((v64 - before) / self._dt).astype(dtype), sensors[:, -1].astype(dtype))
        return tuple(x.reshape(*batch, x.shape[-1]) for x in out)

    def _host_forward(self, qpos, qpos_rest, qvel, qvel_rest, ctrl, *fields):
        batch, dtype = qpos.shape[:-1], qpos.dtype
        qpos, qpos_rest, qvel, qvel_rest, ctrl = [np.reshape(x, (-1, x.shape[-1]))
                                                  for x in (qpos, qpos_rest, qvel, qvel_rest, ctrl)]
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
        state = MujocoState(qpos=qpos, qvel=qvel, qpos_rest=zeros(qpos), qvel_rest=zeros(qvel), ctrl=ctrl,
                            warmstart=zeros(qvel), sensordata=jp.zeros(self.model.nsensordata, qpos.dtype),
                            force_sensors=self._force_ids)
        return self.forward(sys, state)

    def place(self, state, qpos, qvel, ctrl, where=True):
        zeros = jp.zeros_like
        fields = {"qpos": qpos, "qvel": qvel, "ctrl": ctrl, "qpos_rest": zeros(state.qpos_rest),
                  "qvel_rest": zeros(state.qvel_rest), "warmstart": zeros(state.warmstart)}
        return state.replace(**{k: jp.where(where, v, getattr(state, k)) for k, v in fields.items()})

    def forward(self, sys, state):
        shape = jax.ShapeDtypeStruct((self.model.nsensordata,), state.qpos.dtype)
        sensordata = jax.pure_callback(self._host_forward, shape, state.qpos, state.qpos_rest, state.qvel,
                                       state.qvel_rest, state.ctrl, *self._fields_of(sys), vmap_method="broadcast_all")
        return state.replace(sensordata=sensordata)

    def step(self, sys, state, ctrl, qvel):
        pushed = qvel != state.qvel  # a changed velocity (a push) drops its float64 remainder
        qvel_rest = jp.where(pushed, 0.0, state.qvel_rest)
        like = lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype)  # noqa: E731
        shapes = (like(state.qpos), like(state.qpos), like(qvel), like(qvel), like(qvel),
                  jax.ShapeDtypeStruct((self.model.nsensordata,), state.qpos.dtype))
        qpos, qpos_rest, qvel, qvel_rest, warmstart, sensordata = jax.pure_callback(
            self._host_step, shapes, state.qpos, state.qpos_rest, qvel, qvel_rest, ctrl.astype(state.qpos.dtype),
            state.warmstart, *self._fields_of(sys), vmap_method="broadcast_all")
        state = state.replace(qpos=qpos, qpos_rest=qpos_rest, qvel=qvel, qvel_rest=qvel_rest, ctrl=ctrl,
                              warmstart=warmstart, sensordata=sensordata)
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
