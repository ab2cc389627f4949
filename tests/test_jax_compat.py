"""footforge.rl.jax_compat: the device_put_replicated that Brax 0.14.2 needs on JAX >= 0.10, compared
with JAX 0.9's own (the pinned set) on values, dtypes, shapes, shardings and device placement."""

import os
import subprocess
import sys
import warnings

import jax
import jax.numpy as jp
import numpy as np
import pytest

from footforge.rl import jax_compat


def _real():
    """JAX's own device_put_replicated, or None: on JAX >= 0.10 (or once jax_compat.install() has
    put the shim there) there is nothing to compare with, and comparing the shim with itself could
    not fail. CI's pinned JAX 0.9.2 has it, so these tests run there."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        own = getattr(jax, "device_put_replicated", None)
    return None if own is jax_compat.device_put_replicated else own


def _tree():
    return {
        "w": jp.arange(6.0).reshape(2, 3),
        "n": np.int32(7),
        "s": 1.5,
        "b": np.array([True, False]),
        "steps": jp.zeros((), jp.uint32),
        "nested": (jp.ones(4, jp.bfloat16), [np.float64(2.0)]),
    }


def _check_same(ours, real):
    assert jax.tree_util.tree_structure(ours) == jax.tree_util.tree_structure(real)
    for a, b in zip(jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(real)):
        assert a.shape == b.shape and a.dtype == b.dtype and a.weak_type == b.weak_type
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        assert a.sharding == b.sharding, (a.sharding, b.sharding)
        assert [s.device for s in a.addressable_shards] == [s.device for s in b.addressable_shards]
        for sa, sb in zip(a.addressable_shards, b.addressable_shards):
            np.testing.assert_array_equal(np.asarray(sa.data), np.asarray(sb.data))


@pytest.mark.skipif(_real() is None, reason="this JAX has no device_put_replicated to compare with")
def test_shim_matches_jax_device_put_replicated():
    devices = jax.local_devices()
    _check_same(jax_compat.device_put_replicated(_tree(), devices), _real()(_tree(), devices))
    with pytest.raises(ValueError):
        jax_compat.device_put_replicated(_tree(), [])


def test_install_adds_only_what_is_missing():
    before = _real()
    added = jax_compat.install()
    if before is not None:  # the pinned JAX: left alone
        assert added == [] and _real() is before
    else:
        assert added == ["device_put_replicated"] and _real() is jax_compat.device_put_replicated


SCRIPT = """
import warnings, jax, jax.numpy as jp, numpy as np
from footforge.rl import jax_compat
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    real = jax.device_put_replicated
tree = {"w": jp.arange(6.0).reshape(2, 3), "s": 1.5, "i": np.int32(3)}
devices = jax.local_devices()
assert len(devices) == 2
ours, theirs = jax_compat.device_put_replicated(tree, devices), real(tree, devices)
for a, b in zip(jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(theirs)):
    assert a.shape == b.shape == (2,) + np.shape(a)[1:] and a.dtype == b.dtype and a.sharding == b.sharding
    assert [s.device for s in a.addressable_shards] == [s.device for s in b.addressable_shards] == devices
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # inside pmap each device sees its own copy
    np.testing.assert_array_equal(np.asarray(jax.pmap(lambda x: x * 2)(a)), np.asarray(b) * 2)
print("ok")
"""


@pytest.mark.skipif(_real() is None, reason="this JAX has no device_put_replicated to compare with")
def test_shim_matches_on_two_devices():
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2", JAX_PLATFORMS="cpu")
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and done.stdout.strip().endswith("ok"), done.stderr[-3000:]


def _backend_compiles(fn) -> int:
    """How many programs XLA compiled while fn ran (JAX's monitoring events)."""
    events = []

    def listener(name, _seconds, **_):
        events.append(name)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        fn()
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    return events.count("/jax/core/compile/backend_compile_duration")


def test_state_replicated_on_the_pmap_axis_spares_the_second_compilation():
    """Brax's PPO replicates its training state with jax.device_put_replicated and feeds each
    epoch's pmap the previous epoch's outputs. Laid out on JAX 0.9's own axis, the second call
    compiles the epoch again; on the pmap's axis 'i' (replicated_on_pmap_axis) it does not."""
    devices = jax.local_devices()[:1]
    tree = {"w": jp.arange(3.0), "n": jp.zeros((), jp.int32)}

    def second_call_compiles(state) -> int:
        epoch = jax.pmap(lambda s: {"w": jp.sin(s["w"]) + 1.0, "n": s["n"] + 1}, axis_name=jax_compat.BRAX_PMAP_AXIS)
        out = epoch(state)
        return _backend_compiles(lambda: jax.block_until_ready(epoch(out)))

    assert second_call_compiles(jax_compat.device_put_replicated(tree, devices)) == 1  # JAX 0.9's layout
    with jax_compat.replicated_on_pmap_axis():
        state = jax.device_put_replicated(tree, devices)  # what Brax calls
    assert second_call_compiles(state) == 0


def test_replicated_on_pmap_axis_puts_back_what_jax_had(monkeypatch):
    def own():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return getattr(jax, "device_put_replicated", None), "device_put_replicated" in vars(jax)

    before = own()
    with jax_compat.replicated_on_pmap_axis():
        placed = jax.device_put_replicated(jp.zeros(2), jax.local_devices()[:1])
        assert placed.sharding.mesh.axis_names == (jax_compat.BRAX_PMAP_AXIS,)
    assert own() == before
    # A JAX without the function (0.10 and later, before install()) is left without it.
    monkeypatch.delitem(vars(jax), "device_put_replicated", raising=False)

    def no_such_name(name):
        raise AttributeError(name)

    monkeypatch.setattr(jax, "__getattr__", no_such_name, raising=False)
    assert not hasattr(jax, "device_put_replicated")
    with jax_compat.replicated_on_pmap_axis():
        assert callable(jax.device_put_replicated)
    assert not hasattr(jax, "device_put_replicated")


def test_ppo_training_runs_with_the_state_on_the_pmap_axis(monkeypatch):
    """footforge.rl.train hands Brax a jax.device_put_replicated that lays the state on 'i' and an
    Evaluator whose first state is committed."""
    from footforge.rl import train

    seen = {}

    class FakePPO:
        @staticmethod
        def train(**kwargs):
            from brax.training import acting

            seen["axes"] = jax.device_put_replicated(jp.zeros(1), jax.local_devices()[:1]).sharding.mesh.axis_names
            seen["evaluator"] = acting.Evaluator.__name__

    monkeypatch.setattr(train, "network_factory", lambda *a: None)
    ppo = train.PPOConfig()
    env_config = type("C", (), {"episode_steps": 10, "privileged_critic": False})()
    train._run_ppo(FakePPO, None, env_config, ppo, 10, 1, None, 0, None, None, None, lambda env: None)
    assert seen == {"axes": (jax_compat.BRAX_PMAP_AXIS,), "evaluator": "CommittedEvaluator"}


def test_evaluator_with_a_committed_first_state_compiles_its_unroll_once():
    """Brax's Evaluator donates its evaluation state from one evaluation to the next; the first
    state, from a jitted reset of uncommitted keys, is laid out differently from the later ones,
    and the second evaluation compiles the unroll again, unless evaluator_state_committed."""
    from brax import envs
    from brax.training import acting

    from footforge.envs.wrappers import PolicySideWrapper

    # Brax's toy environment, its states strongly typed as footforge's environments return them
    # (a weak type that flips between reset and step would recompile for another reason).
    env = PolicySideWrapper(envs.training.wrap(envs.get_environment("fast"), episode_length=5))

    def policy_factory(params):
        return lambda obs, key: (jp.zeros(obs.shape[:-1] + (1,)) + params, {})

    def second_evaluation_compiles() -> int:
        evaluator = acting.Evaluator(
            env, policy_factory, num_eval_envs=2, episode_length=5, action_repeat=1, key=jax.random.PRNGKey(0)
        )
        # Parameters committed to the device, as Brax's PPO hands them over (unpmapped).
        params = jax.device_put(jp.float32(0.0), jax.local_devices()[0])
        evaluator.run_evaluation(params, {})
        return _backend_compiles(lambda: evaluator.run_evaluation(params, {}))

    assert second_evaluation_compiles() >= 1  # Brax as released
    with jax_compat.evaluator_state_committed():
        assert second_evaluation_compiles() == 0
    assert acting.Evaluator.__name__ == "Evaluator"  # put back
