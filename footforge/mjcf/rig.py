"""The single-foot drop-test rig: one foot under a vertical slider carrying a payload, over a floor."""

from __future__ import annotations

from dm_control import mjcf

from footforge.inputs.params import VariantParams
from footforge.mjcf.elements import add_default_classes
from footforge.mjcf.foot import FootModel, clone
from footforge.mjcf.robot import BuiltModel, add_passive_sensors, set_options
from footforge.mjcf.scene import add_floor
from footforge.mjcf.writing import compile_model


def build_rig(
    foot: FootModel | None,
    ball_radius: float | None,
    *,
    variant: str,
    params: VariantParams,
    friction: float,
    mount_quat=None,
) -> BuiltModel:
    """One foot under a vertical slider carrying the payload, over a floor (the drop-test rig).

    The slider's value is the foot mount's height (its zero puts the mount at z = 0); keyframe
    'reference' rests the foot's lowest point on the floor with the foot at its reference pose,
    and so does qpos0 (the carriage is authored there, the slider's `ref` keeps its meaning).
    `mount_quat` (wxyz) tilts the foot mount relative to the carriage: a leg meeting the ground at an
    angle.
    """
    root = mjcf.RootElement(model=f"foot_rig_{variant}")
    set_options(root, variant, params)
    add_default_classes(root, friction=friction, contact_solref=params.contact_solref_for(variant))
    add_floor(root)
    carriage = root.worldbody.add("body", name="carriage")
    slider = carriage.add("joint", name="slider", type="slide", axis=[0, 0, 1], damping=params.rig_slider_damping)
    carriage.add("inertial", pos=[0, 0, 0.1], mass=params.rig_payload_mass, diaginertia=[0.05, 0.05, 0.05])
    carriage.add(
        "geom",
        name="payload_visual",
        dclass="visual",
        type="box",
        size=[0.04, 0.04, 0.04],
        pos=[0, 0, 0.1],
        rgba=[0.3, 0.3, 0.35, 1],
    )
    mount = carriage.add(
        "site", name="mount", size=[0.005], group=4, quat=list(mount_quat) if mount_quat is not None else None
    )
    root.sensor.add("jointpos", name="slider_pos", joint="slider")
    root.sensor.add("jointvel", name="slider_vel", joint="slider")
    if foot is None:  # the ball foot: a sphere whose centre is the mount (the default mount offset)
        # ball_radius is given with the ball foot (foot None)
        carriage.add("geom", name="ball_collision", dclass="collision", type="sphere", size=[ball_radius])
        carriage.add("site", name="touchdown", pos=[0, 0, -ball_radius], size=[0.005], group=4)  # type: ignore[operator]
        lowest = -ball_radius  # type: ignore[operator]
    else:
        rig_foot = clone(foot, "foot")
        add_passive_sensors(rig_foot.mjcf, rig_foot.passive_joints)
        mount.attach(rig_foot.mjcf)
        lowest = foot.touchdown[2]
    carriage.pos = [0.0, 0.0, -lowest]
    slider.ref = -lowest
    mj = compile_model(root)
    qpos = mj.qpos0.copy()
    qpos[mj.jnt_qposadr[mj.joint("slider").id]] = -lowest
    if foot is not None:
        for joint, value in foot.reference_qpos.items():
            qpos[mj.jnt_qposadr[mj.joint(f"foot/{joint}").id]] = value
    root.keyframe.add("key", name="reference", qpos=qpos)
    return BuiltModel(root, "reference")
