"""Standing still in the built scenes: the `stand` keyframe is where `home` comes to rest, and
from it a robot holding its targets neither sinks nor slides (footforge.validate.stance)."""

import mujoco
import numpy as np
import pytest

from footforge.validate.stance import stand


@pytest.mark.parametrize("variant", ["ball", "aff", "aof"])
def test_robot_standing_neither_sinks_nor_slides(built, variant):
    model = mujoco.MjModel.from_xml_path(str(built[variant][0] / "scene.xml"))
    still = stand(model, keyframe="stand", seconds=10.0, settle_s=0.5)
    assert still.finite
    assert still.drop_after_settle_m < 0.010 and still.slip_after_settle_m < 0.005, still
    # Computed the other way: started at `home` (legs at the default angles, unloaded), the robot
    # falls into the `stand` pose and stays there.
    fallen = stand(model, keyframe="home", seconds=5.0, settle_s=4.0)
    assert fallen.finite
    assert abs(fallen.base_height_settled_m - still.base_height_start_m) < 0.002, (fallen, still)
    assert fallen.base_height_start_m - still.base_height_start_m > 0.02  # home is not a rest pose


def test_stand_keyframe_holds_the_default_targets(built):
    from footforge import constants as C

    model = mujoco.MjModel.from_xml_path(str(built["aof"][0] / "scene.xml"))
    ctrl = model.key("stand").ctrl
    expected = [C.DEFAULT_JOINT_ANGLES_RAD[model.actuator(a).name] for a in range(model.nu)]
    np.testing.assert_allclose(ctrl, expected)
    np.testing.assert_allclose(ctrl, model.key("home").ctrl)


@pytest.mark.parametrize("variant", ["ball", "aof"])
def test_the_stance_rests_on_static_friction(built, variant):
    """Why soft friction creeps (EnvConfig.contact_model): at `stand` the feet carry the robot's
    weight (the vertical ground forces sum to m g, computed from the contacts and from the masses)
    and push sideways against each other (horizontal forces cancelling in sum, each a large
    fraction of its foot's load); without friction the PD legs splay into a crouch."""
    from footforge.validate.stance import foot_loads, frictionless_rest

    model = mujoco.MjModel.from_xml_path(str(built[variant][0] / "scene.xml"))
    loads = foot_loads(model)
    weight = model.body_subtreemass[0] * -model.opt.gravity[2]
    assert abs(loads.forces_n[:, 2].sum() - weight) < 0.005 * weight
    assert np.abs(loads.forces_n[:, :2].sum(0)).max() < 0.01 * weight  # at rest: no net sideways force
    assert loads.sideways_ratio.min() > 0.3, loads.sideways_ratio
    height, splay = frictionless_rest(model)
    assert model.key("stand").qpos[2] - height > 0.1 and splay > 0.1, (height, splay)
