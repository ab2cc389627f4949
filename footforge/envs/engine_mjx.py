"""The `mjx` engine (footforge.envs.engine): MuJoCo MJX steps the robots in JAX.

Its state is MJX's own `mjx.Data`. Foot contacts and their normal forces come from MJX's
contact slots (footforge.envs.mjx_private: the geoms and distances of each slot), the probe
points from `geom_xpos` / `geom_xmat`.
"""

from __future__ import annotations

import jax
import jax.numpy as jp
from mujoco import mjx

from footforge.envs import contacts, mjx_private


class MjxPhysics:
    name = "mjx"

    def __init__(self, config, robot, probe_geoms, probe_local):
        self._decimation = config.decimation
        self._category = jp.asarray(robot.geom_category)
        self._floor = robot.floor_geom
        self._probe_geoms, self._probe_local = jp.asarray(probe_geoms), jp.asarray(probe_local, jp.float32)
        self._foot_sites = jp.asarray(robot.foot_sites)

    def start(self, sys, qpos, qvel, ctrl):
        return mjx.forward(sys, self.place(mjx.make_data(sys), qpos, qvel, ctrl))

    def place(self, state, qpos, qvel, ctrl, where=True):
        fields = {"qpos": qpos, "qvel": qvel, "ctrl": ctrl, "qacc_warmstart": jp.zeros_like(state.qacc_warmstart)}
        return state.replace(**{k: jp.where(where, v, getattr(state, k)) for k, v in fields.items()})

    def forward(self, sys, state):
        return mjx.forward(sys, state)

    def step(self, sys, state, ctrl, qvel):
        def physics(d, _):
            return mjx.step(sys, d), None

        state, _ = jax.lax.scan(physics, state.replace(ctrl=ctrl, qvel=qvel), None, length=self._decimation)
        return state

    def foot_contacts(self, sys, state):
        return contacts.foot_contacts(self._category, self._floor, *mjx_private.contacts(state))

    def foot_forces(self, sys, state):
        normal, index = mjx_private.contact_normal_forces(sys, state)
        geoms, dist = mjx_private.contacts(state)
        return contacts.foot_normal_forces(self._category, self._floor, geoms[index], dist[index], normal)

    def probe_points(self, state):
        g = self._probe_geoms
        return state.geom_xpos[g] + jp.einsum("pij,pj->pi", state.geom_xmat[g], self._probe_local)

    def foot_positions(self, state):
        return state.site_xpos[self._foot_sites]
