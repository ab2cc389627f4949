"""The policy and value networks: Brax PPO's, every parameter float32 and the policy's output
layer scaled at initialisation (PPOConfig.policy_output_init_scale)."""

from __future__ import annotations

import dataclasses
import functools

from footforge.rl.config import PPOConfig


def network_factory(ppo: PPOConfig, privileged: bool = False):
    """Brax's PPO networks; with `privileged` (EnvConfig.privileged_critic) the value network
    reads the observation dict's "privileged_state" and the policy its "state"."""
    from brax.training.agents.ppo import networks as ppo_networks
    from flax import linen

    keys = {"policy_obs_key": "state", "value_obs_key": "privileged_state"} if privileged else {}

    # Brax records the factory's keyword defaults (inspect.signature, which follows __wrapped__)
    # in ppo_network_config.json: the wrapper keeps make_ppo_networks' signature.
    @functools.wraps(ppo_networks.make_ppo_networks)
    def float32_networks(*args, **kwargs):
        # Under JAX's x64 mode (EnvConfig.float64_physics) Brax's log-std parameter is made in
        # float64 (jnp.full of a Python float), and optax's inject_hyperparams then makes Adam's
        # decay rates float64 too, which turns the float32 parameters' moments float64 and breaks
        # PPO's minibatch scan. Every parameter is made float32 (a no-op without x64).
        networks = ppo_networks.make_ppo_networks(*args, **kwargs)
        return dataclasses.replace(
            networks,
            policy_network=_float32_init(networks.policy_network, ppo.policy_output_init_scale),
            value_network=_float32_init(networks.value_network),
        )

    return functools.partial(
        float32_networks,
        policy_hidden_layer_sizes=ppo.policy_hidden_layers,
        value_hidden_layer_sizes=ppo.value_hidden_layers,
        activation=linen.elu,
        distribution_type="normal",
        noise_std_type="log",
        init_noise_std=ppo.init_noise_std,
        **({"mean_clip_scale": ppo.policy_mean_clip} if ppo.policy_mean_clip is not None else {}),
        **keys,
    )


def _float32_init(network, output_scale: float = 1.0):
    """`network` (Brax's FeedForwardNetwork) whose init returns float32 parameters, the policy's
    output (mean) layer, "Dense_0", scaled by `output_scale` (PPOConfig.policy_output_init_scale)."""
    import jax
    import jax.numpy as jp

    def init(*args, **kwargs):
        params = network.init(*args, **kwargs)
        if output_scale != 1.0:
            inner = dict(params["params"])
            inner["Dense_0"] = jax.tree_util.tree_map(lambda x: x * output_scale, inner["Dense_0"])
            params = dict(params) | {"params": inner}
        return jax.tree_util.tree_map(
            lambda x: x.astype(jp.float32) if jp.issubdtype(x.dtype, jp.floating) else x, params
        )

    return dataclasses.replace(network, init=init)
