"""Domain randomisation of the MJX model, one draw per robot, in the form Brax's PPO takes.

`randomizer(env)` returns `randomization_fn(sys, rng) -> (batched sys, in_axes)` for
`brax.training.agents.ppo.train(randomization_fn=...)`: Brax calls it once with one key per
robot, and its DomainRandomizationVmapWrapper steps robot i with model i (the environment's `sys`
attribute). So each robot keeps its draw for the whole training, as legged_gym draws friction and
added mass once when it creates its environments. What is drawn, and the ranges, are
EnvConfig.randomization's fields.
"""

from __future__ import annotations

import jax
import jax.numpy as jp

from footforge import constants as C
from footforge.envs.config import RandomizationConfig

FIELDS = {
    "friction_range": ("geom_friction",),
    "payload_mass_kg_range": ("body_mass", "body_inertia"),
    "motor_strength_range": ("actuator_gainprm", "actuator_biasprm", "actuator_forcerange"),
}
"""The model fields (MjModel's, and MJX's of the same name) each RandomizationConfig range changes."""


def randomized_fields(config: RandomizationConfig) -> tuple[str, ...]:
    """The model fields `config` randomises (FIELDS of its ranges that are on), in FIELDS' order:
    what an engine that does not step MJX's model must take from each robot's `sys`."""
    return tuple(f for name, fields in FIELDS.items() if getattr(config, name) is not None for f in fields)


def randomize(sys, key, config: RandomizationConfig, base_body: int, actuators) -> dict:
    """One robot's randomised model fields ({Model field: new value}), drawn from `key`.

    Friction: every geom's sliding coefficient set to the draw; MuJoCo takes the larger of the
    two geoms' coefficients, so every robot-ground contact gets exactly the draw. Payload: mass
    added at the base's centre of mass, its rotational inertia scaled by the same factor as its
    mass (a payload spread like the base). Motor strength: the position actuators' kp
    (gainprm[0], -biasprm[1]), kv (-biasprm[2]) and torque limit scaled together.
    """
    k_friction, k_mass, k_motor = jax.random.split(key, 3)
    changes = {}
    if config.friction_range is not None:
        lo, hi = config.friction_range
        friction = jax.random.uniform(k_friction, minval=lo, maxval=hi)
        changes["geom_friction"] = sys.geom_friction.at[:, 0].set(friction)
    if config.payload_mass_kg_range is not None:
        lo, hi = config.payload_mass_kg_range
        added = jax.random.uniform(k_mass, minval=lo, maxval=hi)
        mass = sys.body_mass[base_body]
        changes["body_mass"] = sys.body_mass.at[base_body].add(added)
        changes["body_inertia"] = sys.body_inertia.at[base_body].multiply((mass + added) / mass)
    if config.motor_strength_range is not None:
        lo, hi = config.motor_strength_range
        strength = jax.random.uniform(k_motor, minval=lo, maxval=hi)
        changes["actuator_gainprm"] = sys.actuator_gainprm.at[actuators, 0].multiply(strength)
        changes["actuator_biasprm"] = sys.actuator_biasprm.at[actuators, 1:3].multiply(strength)
        changes["actuator_forcerange"] = sys.actuator_forcerange.at[actuators].multiply(strength)
    assert tuple(changes) == randomized_fields(config), (tuple(changes), randomized_fields(config))
    return changes


def randomizer(env):
    """Brax's randomization_fn for `env` (a LocomotionEnv), or None when nothing is randomised."""
    config = env.config.randomization
    if not config.enabled:
        return None
    base_body = env.robot.model.body(C.BASE_BODY).id
    actuators = jp.asarray(env.robot.actuator_ids)

    def randomization_fn(sys, rng):
        """(the model with the randomised fields batched over rng's robots, vmap in_axes)."""
        changes = jax.vmap(lambda key: randomize(sys, key, config, base_body, actuators))(rng)
        in_axes = jax.tree_util.tree_map(lambda _: None, sys).tree_replace({f: 0 for f in changes})
        return sys.tree_replace(changes), in_axes

    return randomization_fn
