"""Brax training wrappers for environments that restart their own episodes.

Brax's default wrapping (brax.envs.training.wrap) ends with an AutoResetWrapper, which replaces
the physics state of every ended episode with one state recorded at reset. footforge's
environments restart ended episodes inside their own step (a new spawn, and on rough terrain a
curriculum level that must survive the restart), so they are wrapped without it: batched, with
Brax's episode bookkeeping (step count, truncation, episode metrics), and a thin wrapper that
only clears the done flag and the step count of ended episodes before the next step.
"""

from __future__ import annotations

import jax
import jax.numpy as jp
from brax.envs.base import Env, State, Wrapper
from brax.envs.wrappers.training import DomainRandomizationVmapWrapper, EpisodeWrapper, VmapWrapper


def _narrow(x):
    """float32 for floating arrays, int32 for signed integers (the policy's side's precision)."""
    if jp.issubdtype(x.dtype, jp.floating):
        return x.astype(jp.float32)
    return x.astype(jp.int32) if jp.issubdtype(x.dtype, jp.signedinteger) else x


def policy_side(state: State) -> State:
    """`state` with what the policy's side reads and carries (observations, reward, done,
    metrics, info) in float32 and int32, whatever precision the physics (pipeline_state) runs in
    (EnvConfig.float64_physics): PPO's networks, normaliser and loop carries stay float32, and a
    step returns the dtypes it was given (a scan's carry must). A no-op in float32."""
    narrow = lambda tree: jax.tree_util.tree_map(_narrow, tree)  # noqa: E731
    return state.replace(
        obs=narrow(state.obs),
        reward=_narrow(state.reward),
        done=_narrow(state.done),
        metrics=narrow(state.metrics),
        info=narrow(state.info),
    )


class PolicySideWrapper(Wrapper):
    """policy_side on every state the wrapped stack returns, Brax's bookkeeping included: under
    JAX's x64 mode (EnvConfig.float64_physics) Brax's wrappers make their episode counters and
    metrics float64 at reset (JAX's default dtype is then float64) while the environment's steps
    return float32."""

    def reset(self, rng: jax.Array) -> State:
        return policy_side(self.env.reset(rng))

    def step(self, state: State, action: jp.ndarray) -> State:
        return policy_side(self.env.step(state, action))


class SelfResetWrapper(Wrapper):
    """AutoResetWrapper's bookkeeping without its state replacement."""

    def step(self, state: State, action: jp.ndarray) -> State:
        if "steps" in state.info:
            state.info.update(steps=jp.where(state.done, jp.zeros_like(state.info["steps"]), state.info["steps"]))
        return self.env.step(state.replace(done=jp.zeros_like(state.done)), action)


def wrap_for_training(env: Env, episode_length: int, action_repeat: int = 1, randomization_fn=None) -> Wrapper:
    """Brax's training wrapping for self-restarting environments (pass as ppo.train's wrap_env_fn)."""
    env = VmapWrapper(env) if randomization_fn is None else DomainRandomizationVmapWrapper(env, randomization_fn)
    return PolicySideWrapper(SelfResetWrapper(EpisodeWrapper(env, episode_length, action_repeat)))
