"""ANYmal C with a foot variant, its scene, and the single-foot drop-test rig, as MJCF.

The robot comes from its description (parsed by Pinocchio, see urdf_import); adaptive feet are
attached with dm_control's `attach` at each leg's foot mount frame, so their bodies, joints and
sensors are namespaced per leg ('LF_foot/front_arch').
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from dm_control import mjcf
from lxml import etree

from footforge import constants as C
from footforge.errors import CheckFailure
from footforge.foot import FootModel, clone, collision_points, compile_model
from footforge.params import VariantParams
from footforge.urdf_import import (FLOATING_JOINT, MeshAssets, ParsedURDF, add_body_tree, add_default_classes,
                                   add_geoms, inertial_attributes, quat_wxyz)

FLOOR_CONTYPE = 1  # environment geoms touch robot collision geoms (conaffinity 1)


@dataclass
class BuiltModel:
    mjcf: mjcf.RootElement
    keyframe: str
    """Name of the keyframe simulations start from."""


def _options(root: mjcf.RootElement, variant: str, params: VariantParams, *, robot: bool = False) -> None:
    root.compiler.angle = "radian"
    root.compiler.autolimits = True
    # implicitfast integrates joint damping and the actuators' kv implicitly: stable PD at 80/2.
    root.option.integrator = "implicitfast"
    if robot:  # the standing contact model (parameter file, `contact`: cone, impratio, solimp)
        root.option.set_attributes(cone=params.contact_cone, impratio=params.contact_impratio)
    if variant == "full":
        full = params.full
        root.option.set_attributes(timestep=full.timestep, iterations=full.iterations, tolerance=full.tolerance,
                                   solver="Newton")
    else:
        root.option.timestep = params.simplified_timestep


def _add_passive_sensors(foot_root: mjcf.RootElement, joints) -> None:
    for joint in joints:
        foot_root.sensor.add("jointpos", name=f"{joint}_pos", joint=joint)
        foot_root.sensor.add("jointvel", name=f"{joint}_vel", joint=joint)


def build_robot(parsed: ParsedURDF, foot: FootModel | None, *, variant: str, params: VariantParams,
                friction: float, stand_keyframe: bool = True) -> BuiltModel:
    """ANYmal C with four feet of `variant` (`foot` None for the ball feet of the description),
    with keyframes `home` and (unless stand_keyframe is False) `stand`."""
    model = parsed.model
    root = mjcf.RootElement(model=f"anymal_c_{variant}")
    _options(root, variant, params, robot=True)
    add_default_classes(root, friction=friction, contact_solref=params.contact_solref_for(variant),
                        contact_solimp=params.contact_solimp)
    root.default.add("default", dclass="leg").joint.set_attributes(type="hinge")
    actuator_class = root.default.add("default", dclass="leg_actuator")
    actuator_class.position.set_attributes(kp=C.KP_NM_PER_RAD, kv=C.KD_NMS_PER_RAD,
                                           forcerange=[-C.EFFORT_LIMIT_NM, C.EFFORT_LIMIT_NM])
    assets = MeshAssets(root)
    base = root.worldbody.add("body", name=parsed.link_of_joint[FLOATING_JOINT])
    base.add("freejoint", name=C.FLOATING_JOINT)
    base.add("inertial", **inertial_attributes(model.inertias[1]))
    add_geoms(base, parsed, 1, assets)
    bodies = add_body_tree(parsed, base, assets, joint_class=lambda j: "leg")

    def frame_site(link: str, name: str, **kw):
        joint_id, placement = parsed.body_of_link(link)
        return bodies[joint_id].add("site", name=name, pos=np.array(placement.translation),
                                    quat=quat_wxyz(placement.rotation), **kw)

    imu = frame_site(C.IMU_FRAME, "imu", size=[0.01], group=4)
    root.sensor.add("gyro", name="imu_gyro", site=imu)
    root.sensor.add("accelerometer", name="imu_accelerometer", site=imu)
    root.sensor.add("framequat", name="imu_orientation", objtype="site", objname=imu)
    for leg in C.LEGS:
        mount = frame_site(C.FOOT_MOUNT_FRAME.format(leg=leg), f"{leg}_foot_mount", size=[0.005], group=4)
        if foot is None:
            joint_id, _ = parsed.body_of_link(f"{leg}_FOOT")
            body = bodies[joint_id]
            spheres = [g for g in body.find_all("geom") if g.type == "sphere" and str(g.dclass) == "collision"]
            if not spheres:
                raise ValueError(f"{leg}: no ball foot sphere in the description (expand it with foot:=ball)")
            s = spheres[0]
            body.add("site", name=f"{leg}_touchdown", pos=np.asarray(s.pos) - [0, 0, s.size[0]], size=[0.005], group=4)
        else:
            leg_foot = clone(foot, C.FOOT_MODEL_NAME.format(leg=leg))
            _add_passive_sensors(leg_foot.mjcf, leg_foot.passive_joints)
            # The foot's own collision class (namespaced by attach) gets the robot's solimp.
            leg_foot.mjcf.default.find("default", "collision").geom.solimp = list(params.contact_solimp)
            mount.attach(leg_foot.mjcf)
    for joint in C.ACTUATED_JOINTS:
        j = root.find("joint", joint)
        root.actuator.add("position", name=joint, joint=j, dclass="leg_actuator", ctrlrange=j.range)
    _add_home_keyframe(root, foot)
    if stand_keyframe:
        _add_stand_keyframe(root)
    return BuiltModel(root, "home")


def foot_reference_qpos(mj: mujoco.MjModel, foot: FootModel | None, prefix_format: str) -> dict[int, float]:
    """qpos address -> value of every foot joint at the reference pose."""
    values = {}
    if foot is None:
        return values
    for leg in C.LEGS:
        prefix = prefix_format.format(leg=leg)
        for joint, value in foot.reference_qpos.items():
            values[mj.jnt_qposadr[mj.joint(f"{prefix}{joint}").id]] = value
    return values


def _add_home_keyframe(root: mjcf.RootElement, foot: FootModel | None) -> None:
    """Standing at the default joint angles, feet at their reference pose, lowest point on z = 0."""
    mj = compile_model(root)
    data = mujoco.MjData(mj)
    qpos = mj.qpos0.copy()
    for joint, angle in C.DEFAULT_JOINT_ANGLES_RAD.items():
        qpos[mj.jnt_qposadr[mj.joint(joint).id]] = angle
    for adr, value in foot_reference_qpos(mj, foot, C.FOOT_MODEL_NAME + "/").items():
        qpos[adr] = value
    data.qpos[:] = qpos
    mujoco.mj_kinematics(mj, data)
    lowest = collision_points(mj, data, [mj.body(b).name for b in range(1, mj.nbody)])[:, 2].min()
    qpos[2] = -lowest
    ctrl = [C.DEFAULT_JOINT_ANGLES_RAD[mj.actuator(a).name] for a in range(mj.nu)]
    root.keyframe.add("key", name="home", qpos=qpos, ctrl=ctrl)


STAND_SETTLE_MAX_S = 5.0
"""The longest the robot is given to come to rest for the `stand` keyframe, s."""
STAND_REST_QVEL = 1e-2
"""At rest: the base's and the 12 leg joints' velocities below this (m/s, rad/s) for
STAND_REST_HOLD_S (the closed chain's 8-16 g links keep a faint vibration of their own)."""
STAND_REST_HOLD_S = 0.2


def _add_stand_keyframe(root: mjcf.RootElement) -> None:
    """Keyframe `stand`: the robot at rest on flat ground (z = 0) under the home keyframe's PD
    targets, found by simulating it from `home` until it stops moving.

    `home` is a pose, not an equilibrium: at kp 80 N m/rad the legs give under the robot's weight
    (the base settles about 4 cm lower) and an adaptive foot's passive joints turn to their
    loaded angles, so a simulation started there spends its first second falling and bouncing.
    Starting from `stand`, a robot holding its targets does not move (footforge.stance).

    Raises:
      CheckFailure: the robot did not come to rest within STAND_SETTLE_MAX_S.
    """
    spec = mujoco.MjSpec.from_string(root.to_xml_string(), assets=root.get_assets())
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], contype=FLOOR_CONTYPE, conaffinity=1)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    still_steps, needed = 0, int(round(STAND_REST_HOLD_S / model.opt.timestep))
    watched = np.concatenate([np.arange(6), [model.joint(j).dofadr[0] for j in C.ACTUATED_JOINTS]])
    while still_steps < needed:
        if data.time > STAND_SETTLE_MAX_S or not np.isfinite(data.qvel).all():
            dof = int(watched[np.argmax(np.abs(data.qvel[watched]))])
            raise CheckFailure(f"the robot standing at its home keyframe did not come to rest within "
                               f"{STAND_SETTLE_MAX_S:g} s (largest velocity {np.abs(data.qvel[dof]):.3g}, joint "
                               f"'{model.joint(model.dof_jntid[dof]).name}')",
                               fix="check the contact settings (parameter file, `contact`) and the passive joints")
        mujoco.mj_step(model, data)
        still_steps = still_steps + 1 if np.abs(data.qvel[watched]).max() < STAND_REST_QVEL else 0
    root.keyframe.add("key", name="stand", qpos=data.qpos.copy(), ctrl=data.ctrl.copy())


def build_rig(foot: FootModel | None, ball_radius: float | None, *, variant: str, params: VariantParams,
              friction: float, mount_quat=None) -> BuiltModel:
    """One foot under a vertical slider carrying the payload, over a floor (the drop-test rig).

    The slider's zero puts the foot mount at z = 0; keyframe 'reference' rests the foot's lowest
    point on the floor with the foot at its reference pose. `mount_quat` (wxyz) tilts the foot
    mount relative to the carriage: a leg meeting the ground at an angle.
    """
    root = mjcf.RootElement(model=f"foot_rig_{variant}")
    _options(root, variant, params)
    add_default_classes(root, friction=friction, contact_solref=params.contact_solref_for(variant))
    _add_floor(root)
    carriage = root.worldbody.add("body", name="carriage")
    carriage.add("joint", name="slider", type="slide", axis=[0, 0, 1], damping=params.rig_slider_damping)
    carriage.add("inertial", pos=[0, 0, 0.1], mass=params.rig_payload_mass, diaginertia=[0.05, 0.05, 0.05])
    carriage.add("geom", name="payload_visual", dclass="visual", type="box", size=[0.04, 0.04, 0.04],
                 pos=[0, 0, 0.1], rgba=[0.3, 0.3, 0.35, 1])
    mount = carriage.add("site", name="mount", size=[0.005], group=4,
                         quat=list(mount_quat) if mount_quat is not None else None)
    root.sensor.add("jointpos", name="slider_pos", joint="slider")
    root.sensor.add("jointvel", name="slider_vel", joint="slider")
    if foot is None:  # the ball foot: a sphere whose centre is the mount (the default mount offset)
        carriage.add("geom", name="ball_collision", dclass="collision", type="sphere", size=[ball_radius])
        carriage.add("site", name="touchdown", pos=[0, 0, -ball_radius], size=[0.005], group=4)
        lowest = -ball_radius
    else:
        rig_foot = clone(foot, "foot")
        _add_passive_sensors(rig_foot.mjcf, rig_foot.passive_joints)
        mount.attach(rig_foot.mjcf)
        lowest = foot.touchdown[2]
    mj = compile_model(root)
    qpos = mj.qpos0.copy()
    qpos[mj.jnt_qposadr[mj.joint("slider").id]] = -lowest
    if foot is not None:
        for joint, value in foot.reference_qpos.items():
            qpos[mj.jnt_qposadr[mj.joint(f"foot/{joint}").id]] = value
    root.keyframe.add("key", name="reference", qpos=qpos)
    return BuiltModel(root, "reference")


def _add_floor(root: mjcf.RootElement) -> None:
    grid = root.asset.add("texture", name="grid", type="2d", builtin="checker", width=512, height=512,
                          rgb1=[0.2, 0.3, 0.4], rgb2=[0.1, 0.2, 0.3])
    material = root.asset.add("material", name="grid", texture=grid, texrepeat=[8, 8], reflectance=0.1)
    root.worldbody.add("light", name="sun", pos=[0, 0, 3], dir=[0, 0, -1], directional=True)
    root.worldbody.add("geom", name="floor", type="plane", size=[0, 0, 0.05], material=material,
                       contype=FLOOR_CONTYPE, conaffinity=1)


def scene_xml(robot_file: str, variant: str) -> str:
    """scene.xml: the robot file included, plus a floor and a light (MuJoCo Menagerie's layout)."""
    root = mjcf.RootElement(model=f"anymal_c_{variant}_scene")
    _add_floor(root)
    root.visual.headlight.set_attributes(diffuse=[0.6, 0.6, 0.6], ambient=[0.3, 0.3, 0.3])
    root.statistic.set_attributes(center=[0, 0, 0.3], extent=1.2)
    tree = etree.fromstring(root.to_xml_string().encode())
    for default in tree.findall("default"):  # dm_control's empty top class clashes with the robot's
        tree.remove(default)
    tree.insert(0, etree.Element("include", file=robot_file))
    return etree.tostring(tree, pretty_print=True, encoding="unicode")
