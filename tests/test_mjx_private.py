"""footforge.envs.mjx_private: the MJX internals footforge reads are where and what it expects.

These fail when a new MJX moves or reshapes them; the physics (a resting sphere's contact force
equals its weight) says the adapter reads the right slots."""

import mujoco
import numpy as np
import pytest

mjx = pytest.importorskip("mujoco.mjx")

from footforge.envs import mjx_private  # noqa: E402

SCENE = """
<mujoco>
  <option timestep="0.002"/>
  <asset><hfield name="ground" nrow="5" ncol="5" size="1 1 0.1 0.05"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1" condim="3"/>
    <geom name="bumps" type="hfield" hfield="ground" pos="5 0 0" condim="3"/>
    <body name="ball" pos="0 0 0.1">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.1" mass="2" condim="3"/>
    </body>
    <body name="brick" pos="5 0 0.3">
      <freejoint/>
      <geom name="brick" type="box" size="0.05 0.03 0.02" mass="0.5" condim="3"/>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def settled():
    import jax

    model = mujoco.MjModel.from_xml_string(SCENE)
    mjx_model = mjx.put_model(model)
    data = mjx.make_data(mjx_model)
    step = jax.jit(lambda d: jax.lax.fori_loop(0, 500, lambda _, x: mjx.step(mjx_model, x), d))
    return model, mjx_model, step(data)


def test_contacts_name_the_touching_pair(settled):
    model, _, data = settled
    geoms, dist = mjx_private.contacts(data)
    assert geoms.ndim == 2 and geoms.shape[1] == 2 and dist.shape == geoms.shape[:1]
    touching = {tuple(sorted(int(g) for g in pair)) for pair, d in zip(np.asarray(geoms), np.asarray(dist)) if d < 0}
    assert (model.geom("floor").id, model.geom("ball").id) in touching


def test_the_resting_ball_s_normal_force_is_its_weight(settled):
    model, mjx_model, data = settled
    normal, index = mjx_private.contact_normal_forces(mjx_model, data)
    geoms, dist = (np.asarray(a) for a in mjx_private.contacts(data))
    ball = model.geom("ball").id
    on_ball = np.array([ball in geoms[i] and dist[i] < 0 for i in np.asarray(index)])
    weight = 2.0 * -model.opt.gravity[2]
    np.testing.assert_allclose(float(np.asarray(normal)[on_ball].sum()), weight, rtol=0.02)


def test_heightfield_bounds_read_and_replace(settled):
    model, mjx_model, _ = settled
    bounds = mjx_private.heightfield_bounds(mjx_model)
    np.testing.assert_allclose(bounds, model.geom_rbound)  # MJX's default: the geoms' own bounds
    bounds[model.geom("brick").id] = 0.042
    replaced = mjx_private.with_heightfield_bounds(mjx_model, bounds)
    assert mjx_private.heightfield_bounds(replaced)[model.geom("brick").id] == pytest.approx(0.042)
    assert mjx_private.heightfield_bounds(mjx_model)[model.geom("brick").id] == pytest.approx(
        model.geom_rbound[model.geom("brick").id]
    )  # a copy: the original model keeps its bounds
