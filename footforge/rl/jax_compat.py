"""Compatibility of the pinned Brax (0.14.2) with newer JAX (0.10 and later, e.g. a GPU machine's 0.11).

Brax 0.14.2's PPO replicates its training state over the local devices with
`jax.device_put_replicated`, which JAX deprecated in 0.9 and removed in 0.10 (fixed on Brax's main
branch, not released). `install()` puts back a function with the same contract, built from public
APIs, and only where JAX lacks the attribute: on the pinned JAX 0.9.2 nothing changes.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

_AXIS = "_device_put_replicated"  # JAX 0.9's own mesh axis name for this layout


def device_put_replicated(x: Any, devices: Sequence) -> Any:
    """`x` (an array, scalar or pytree of them) stacked along a new leading axis of size
    len(devices), slice i held by devices[i]: JAX 0.9's `jax.device_put_replicated`, whose
    result is sharded as NamedSharding(Mesh(devices, (axis,)), P(axis))."""
    import jax
    import numpy as np
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    if not isinstance(devices, Sequence) or not devices:
        raise ValueError("`devices` argument to `device_put_replicated must be a non-empty sequence.")
    sharding = NamedSharding(Mesh(np.array(devices), (_AXIS,)), PartitionSpec(_AXIS))

    def replicate(leaf):
        # The copies stacked, then split over the devices by the sharding: slice i lands on
        # devices[i]. (Dtype and weak type kept, as JAX 0.9 kept them.)
        leaf = jax.numpy.asarray(leaf)
        return jax.device_put(jax.numpy.broadcast_to(leaf[None], (len(devices),) + leaf.shape), sharding)

    return jax.tree_util.tree_map(replicate, x)


def missing() -> list[str]:
    """Names Brax needs that this JAX lacks."""
    import jax

    with warnings.catch_warnings():  # JAX 0.9 warns on access to its deprecated name
        warnings.simplefilter("ignore")
        return [] if hasattr(jax, "device_put_replicated") else ["device_put_replicated"]


def install() -> list[str]:
    """Adds the missing names to the `jax` module; returns those it added (none on JAX < 0.10)."""
    import jax

    added = missing()
    if "device_put_replicated" in added:
        jax.device_put_replicated = device_put_replicated
    return added
