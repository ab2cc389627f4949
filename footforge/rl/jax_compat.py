"""Brax 0.14.2's PPO with the JAX it runs on: the pinned 0.9.2 and newer ones (a GPU machine's 0.11).

Brax 0.14.2's PPO replicates its training state over the local devices with
`jax.device_put_replicated`, which JAX deprecated in 0.9 and removed in 0.10 (fixed on Brax's main
branch, not released). `install()` puts back a function with the same contract, built from public
APIs, and only where JAX lacks the attribute: on the pinned JAX 0.9.2 nothing changes.

That replicated state is laid out on a mesh axis named '_device_put_replicated', while the arrays
Brax's pmapped training epoch returns lie on its pmap axis 'i'. The two layouts differ, so the
second epoch's call (given the first one's outputs) misses the compiled program and compiles the
whole training epoch again (measured on this project's 2-core CPU: 22 s for flat ball feet, 29 s
for rough AOF; minutes on a GPU machine). `replicated_on_pmap_axis()` lays the state on 'i' from
the start, for the duration of one training call (google/brax pull request 674 makes the same
change inside Brax, unreleased).

Brax's evaluator has the same trouble with its donated evaluation state: the first one comes from
a jitted reset of uncommitted keys (no device fixed), every later one from the previous
evaluation's outputs (committed to the device), so the second evaluation compiles the whole
evaluation unroll again. `evaluator_state_committed()` commits the first state to the device the
later ones live on. `brax_compiles_once()` applies both.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

_AXIS = "_device_put_replicated"  # JAX 0.9's own mesh axis name for this layout
BRAX_PMAP_AXIS = "i"
"""The axis name of Brax PPO's pmapped functions (brax.training.agents.ppo.train._PMAP_AXIS_NAME)."""


def device_put_replicated(x: Any, devices: Sequence, axis: str = _AXIS) -> Any:
    """`x` (an array, scalar or pytree of them) stacked along a new leading axis of size
    len(devices), slice i held by devices[i]: JAX 0.9's `jax.device_put_replicated`, whose
    result is sharded as NamedSharding(Mesh(devices, (axis,)), P(axis)) with axis
    '_device_put_replicated' (another `axis` gives the layout of a pmap over that axis name)."""
    import jax
    import numpy as np
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    if not isinstance(devices, Sequence) or not devices:
        raise ValueError("`devices` argument to `device_put_replicated must be a non-empty sequence.")
    sharding = NamedSharding(Mesh(np.array(devices), (axis,)), PartitionSpec(axis))

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


def _replicated_strongly_typed(x: Any, devices: Sequence, axis: str) -> Any:
    """device_put_replicated of `x` with its weak types made strong, as Brax's epochs return
    them (its _strip_weak_type): a weakly typed scalar in the initial parameters would make the
    first evaluation's program differ from the later ones'."""
    import jax
    import jax.numpy as jp

    def strong(leaf):
        leaf = jp.asarray(leaf)
        return leaf.astype(leaf.dtype)  # astype to its own dtype drops the weak type

    return device_put_replicated(jax.tree_util.tree_map(strong, x), devices, axis=axis)


@contextmanager
def replicated_on_pmap_axis(axis: str = BRAX_PMAP_AXIS) -> Iterator[None]:
    """While active, `jax.device_put_replicated` lays its copies on the mesh axis `axis`, the
    layout of the outputs of a pmap over that axis name: Brax's PPO then compiles its training
    epoch once instead of twice. The function JAX had (or its absence) is put back on exit."""
    import jax

    # JAX 0.9 serves its deprecated name through the module's __getattr__ (with a warning), not
    # from the module's namespace: only what the namespace held is put back.
    namespace = vars(jax)
    before = namespace.get("device_put_replicated")
    jax.device_put_replicated = functools.partial(_replicated_strongly_typed, axis=axis)
    try:
        yield
    finally:
        if before is None:
            del jax.device_put_replicated
        else:
            jax.device_put_replicated = before


@contextmanager
def evaluator_state_committed() -> Iterator[None]:
    """While active, Brax's acting.Evaluator (as Brax's PPO creates it) starts from a donated
    evaluation state committed to the first local device, as the states its evaluations return
    are: its evaluation unroll compiles once instead of twice."""
    import jax
    from brax.training import acting

    original = acting.Evaluator

    class CommittedEvaluator(acting.Evaluator):  # `original`, replaced below
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self._eval_state_to_donate = jax.device_put(self._eval_state_to_donate, jax.local_devices()[0])  # type: ignore[has-type]

    acting.Evaluator = CommittedEvaluator
    try:
        yield
    finally:
        acting.Evaluator = original


@contextmanager
def brax_compiles_once(axis: str = BRAX_PMAP_AXIS) -> Iterator[None]:
    """replicated_on_pmap_axis and evaluator_state_committed together: Brax's PPO then compiles its
    training epoch and its evaluation unroll once each."""
    with replicated_on_pmap_axis(axis), evaluator_state_committed():
        yield
