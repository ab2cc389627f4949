"""ANYmal C with a foot variant, as MJCF, with its `home` and `stand` keyframes.

The robot comes from its description (parsed by Pinocchio, footforge.models.urdf); adaptive feet are
attached with dm_control's `attach` at each leg's foot mount frame, so their bodies, joints and
sensors are namespaced per leg ('LF_foot/front_arch').
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from dm_control import mjcf

from footforge import constants as C
from footforge.errors import CheckFailure
from footforge.inputs.params import VariantParams
from footforge.mjcf.elements import MeshAssets, add_body_tree, add_default_classes, add_geoms, inertial_attributes
from footforge.mjcf.foot import FootModel, clone, collision_points
from footforge.mjcf.scene import FLOOR_CONTYPE
from footforge.mjcf.writing import compile_model
from footforge.models.urdf import FLOATING_JOINT, ParsedURDF, quat_wxyz
from footforge.variants import foot_variant


@dataclass
class BuiltModel:
    mjcf: mjcf.RootElement
    keyframe: str
    """Name of the keyframe simulations start from."""


def set_options(root: mjcf.RootElement, variant: str, params: VariantParams, *, robot: bool = False) -> None:
    root.compiler.angle = "radian"
    root.compiler.autolimits = True
    # implicitfast integrates joint damping and the actuators' kv implicitly: stable PD at 80/2.
    root.option.integrator = "implicitfast"
    if robot:  # the standing contact model (parameter file, `contact`: cone, impratio, solimp)
        root.option.set_attributes(cone=params.contact_cone, impratio=params.contact_impratio)
    if foot_variant(variant).closed_chain:
        full = params.full
        root.option.set_attributes(
            timestep=full.timestep, iterations=full.iterations, tolerance=full.tolerance, solver="Newton"
        )
    else:
        root.option.timestep = params.simplified_timestep


def add_passive_sensors(foot_root: mjcf.RootElement, joints) -> None:
    for joint in joints:
        foot_root.sensor.add("jointpos", name=f"{joint}_pos", joint=joint)
        foot_root.sensor.add("jointvel", name=f"{joint}_vel", joint=joint)


def build_robot(
    parsed: ParsedURDF,
    foot: FootModel | None,
    *,
    variant: str,
    params: VariantParams,
    friction: float,
    stand_keyframe: bool = True,
) -> BuiltModel:
    """ANYmal C with four feet of `variant` (`foot` None for the ball feet of the description),
    with keyframes `home` and (unless stand_keyframe is False) `stand`."""
    model = parsed.model
    root = mjcf.RootElement(model=f"anymal_c_{variant}")
    set_options(root, variant, params, robot=True)
    add_default_classes(
        root, friction=friction, contact_solref=params.contact_solref_for(variant), contact_solimp=params.contact_solimp
    )
    root.default.add("default", dclass="leg").joint.set_attributes(type="hinge")
    actuator_class = root.default.add("default", dclass="leg_actuator")
    actuator_class.position.set_attributes(
        kp=C.KP_NM_PER_RAD, kv=C.KD_NMS_PER_RAD, forcerange=[-C.EFFORT_LIMIT_NM, C.EFFORT_LIMIT_NM]
    )
    assets = MeshAssets(root)
    base = root.worldbody.add("body", name=parsed.link_of_joint[FLOATING_JOINT])
    base.add("freejoint", name=C.FLOATING_JOINT)
    base.add("inertial", **inertial_attributes(model.inertias[1]))
    add_geoms(base, parsed, 1, assets)
    bodies = add_body_tree(parsed, base, assets, joint_class=lambda j: "leg")

    def frame_site(link: str, name: str, **kw):
        joint_id, placement = parsed.body_of_link(link)
        return bodies[joint_id].add(
            "site", name=name, pos=np.array(placement.translation), quat=quat_wxyz(placement.rotation), **kw
        )

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
            add_passive_sensors(leg_foot.mjcf, leg_foot.passive_joints)
            # The foot's own collision class (namespaced by attach) gets the robot's solimp.
            leg_foot.mjcf.default.find("default", "collision").geom.solimp = list(params.contact_solimp)
            mount.attach(leg_foot.mjcf)
    for joint in C.ACTUATED_JOINTS:
        j = root.find("joint", joint)
        root.actuator.add("position", name=joint, joint=j, dclass="leg_actuator", ctrlrange=j.range)
    _add_home_keyframe(root, foot)
    _rest_qpos0_on_floor(root, base)
    if stand_keyframe:
        _add_stand_keyframe(root)
    return BuiltModel(root, "home")


def foot_reference_qpos(mj: mujoco.MjModel, foot: FootModel | None, prefix_format: str) -> dict[int, float]:
    """qpos address -> value of every foot joint at the reference pose."""
    values: dict[int, float] = {}
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
    qpos[2] = -_lowest_collision_z(mj, data)
    ctrl = [C.DEFAULT_JOINT_ANGLES_RAD[mj.actuator(a).name] for a in range(mj.nu)]
    root.keyframe.add("key", name="home", qpos=qpos, ctrl=ctrl)


def _rest_qpos0_on_floor(root: mjcf.RootElement, base: mjcf.Element) -> None:
    """Authors the base where qpos0 (legs straight, the description's zero angles; feet at their
    reference pose) rests the lowest collision point on z = 0: a model opened without a keyframe
    (`python -m mujoco.viewer --mjcf scene.xml`) stands on its straight legs under zero PD targets
    instead of starting with its legs through the floor."""
    mj = compile_model(root)
    base.pos = [0.0, 0.0, -_lowest_collision_z(mj, mujoco.MjData(mj))]


def _lowest_collision_z(mj: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Height of the robot's lowest collision point at data.qpos, m."""
    mujoco.mj_kinematics(mj, data)
    return float(collision_points(mj, data, [mj.body(b).name for b in range(1, mj.nbody)])[:, 2].min())


def _add_stand_keyframe(root: mjcf.RootElement) -> None:
    """Keyframe `stand`: the robot at rest on flat ground (z = 0) under the home keyframe's PD
    targets, found by simulating it from `home` until it stops moving (footforge.rest).

    `home` is a pose, not an equilibrium: at kp 80 N m/rad the legs give under the robot's weight
    (the base settles about 4 cm lower) and an adaptive foot's passive joints turn to their
    loaded angles, so a simulation started there spends its first second falling and bouncing.
    Starting from `stand`, a robot holding its targets does not move (footforge.validate.stance).

    Raises:
      CheckFailure: the robot did not come to rest within footforge.rest.SETTLE_MAX_S.
    """
    from footforge.rest import SETTLE_MAX_S, NoRest, rest_pose

    spec = mujoco.MjSpec.from_string(root.to_xml_string(), assets=root.get_assets())
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], contype=FLOOR_CONTYPE, conaffinity=1)
    try:
        qpos, ctrl = rest_pose(spec.compile())
    except NoRest as e:
        raise CheckFailure(
            f"the robot standing at its home keyframe did not come to rest within {SETTLE_MAX_S:g} s "
            f"(largest velocity {e.speed:.3g}, joint '{e.joint}')",
            fix="check the contact settings (parameter file, `contact`) and the passive joints",
        ) from None
    root.keyframe.add("key", name="stand", qpos=qpos, ctrl=ctrl)
