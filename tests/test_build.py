"""Physics checks of `footforge build` outputs: compile, step, closures, mass properties."""

import json

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from footforge import constants as C
from footforge.inputs.description import default_robot_description, load_description
from footforge.mjcf.foot import collision_points

ADAPTIVE = ("full", "aof", "aff")


class _Warnings:
    """Collects MuJoCo warnings raised while stepping (MuJoCo Menagerie's test fails on any)."""

    @staticmethod
    def of(data):
        return {
            mujoco.mjtWarning(i).name: int(data.warning[i].number)
            for i in range(len(data.warning))
            if data.warning[i].number
        }


def _load(built, variant, name):
    out, _ = built[variant]
    return mujoco.MjModel.from_xml_path(str(out / name))


@pytest.mark.parametrize("variant", ["full", "aof", "aff", "ball"])
def test_outputs_written(built, variant):
    out, report = built[variant]
    for name in ("robot.xml", "scene.xml", "foot_rig.xml", "build_report.json"):
        assert (out / name).is_file()
    assert json.loads((out / "build_report.json").read_text())["variant"] == variant
    assert report["model"]["actuators"] == 12


@pytest.mark.parametrize("variant", ["full", "aof", "aff", "ball"])
def test_robot_steps_one_second_under_random_commands(built, variant):
    model = _load(built, variant, "scene.xml")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    rng = np.random.default_rng(0)
    lo, hi = model.actuator_ctrlrange.T
    home = data.ctrl.copy()
    steps = int(round(1.0 / model.opt.timestep))
    for i in range(steps):
        if i % max(1, int(0.02 / model.opt.timestep)) == 0:  # new command at 50 Hz
            data.ctrl[:] = np.clip(home + rng.uniform(-0.3, 0.3, model.nu), lo, hi)
        mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    assert _Warnings.of(data) == {}


@pytest.mark.parametrize("variant", ["full", "aof", "aff", "ball"])
def test_rig_drop_settles_under_payload(built, variant):
    """The rig's foot dropped 2 cm with 13 kg settles: the floor then carries the whole weight."""
    model = _load(built, variant, "foot_rig.xml")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("reference").id)
    data.qpos[model.jnt_qposadr[model.joint("slider").id]] += 0.02
    for _ in range(int(round(1.5 / model.opt.timestep))):
        mujoco.mj_step(model, data)
    assert _Warnings.of(data) == {}
    weight = sum(model.body_mass[1:]) * -model.opt.gravity[2]
    force = np.zeros(6)
    normal = 0.0
    for i in range(data.ncon):
        mujoco.mj_contactForce(model, data, i, force)
        normal += force[0] * abs(data.contact[i].frame[2])  # frame row 0 is the contact normal
    assert normal == pytest.approx(weight, rel=0.02)


def test_closed_chain_closes_at_reference_and_while_standing(built):
    _, report = built["full"]
    assert report["foot"]["closure_error_at_reference_m"] < 1e-9
    assert report["closure_residual_at_home_m"] < 1e-6
    model = _load(built, "full", "scene.xml")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    closures = [e for e in range(model.neq) if model.eq_type[e] == mujoco.mjtEq.mjEQ_CONNECT]
    assert len(closures) == 12  # three per foot
    worst = 0.0
    for _ in range(int(round(0.5 / model.opt.timestep))):
        mujoco.mj_step(model, data)
        for e in closures:
            a, b = model.eq_obj1id[e], model.eq_obj2id[e]
            worst = max(worst, np.linalg.norm(data.site_xpos[a] - data.site_xpos[b]))
    # Standing loads each foot with ~130 N: the stiff closures may yield tens of microns, not mm.
    assert worst < 2e-4


def test_closed_chain_stops_hold_while_standing(built):
    """Each foot joint's range is a mechanical stop. Standing, ANYmal's 130 N per foot presses the
    arches onto their +-30 deg stops; with MuJoCo's default limit softness (20 ms, scaled by these
    light links' inertia) they went up to 10 deg past them in 1.5 s, and under walking loads the
    arches passed them by up to 100 deg. The build's stops (solreflimit = the closures' solref)
    hold within a degree."""
    model = _load(built, "full", "scene.xml")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    foot = [j for j in range(model.njnt) if model.jnt_limited[j] and "_foot/" in model.joint(j).name]
    assert len(foot) == 4 * 31  # 2 arches, 2 rolls and 27 chain pins per foot
    lo, hi = model.jnt_range[foot].T
    adr = model.jnt_qposadr[foot]
    past = 0.0
    for _ in range(int(round(1.5 / model.opt.timestep))):
        mujoco.mj_step(model, data)
        q = data.qpos[adr]
        past = max(past, float(np.max(np.maximum(q - hi, lo - q))))
    assert np.degrees(past) < 1.0


def _foot_centroidal(model, data, root_body):
    root = model.body(root_body).id
    ids = [b for b in range(model.nbody) if _is_below(model, b, root)]
    m = model.body_mass[ids]
    com = (m[:, None] * data.xipos[ids]).sum(0) / m.sum()
    inertia = np.zeros((3, 3))
    for b in ids:
        R = data.ximat[b].reshape(3, 3)
        r = data.xipos[b] - com
        inertia += R @ np.diag(model.body_inertia[b]) @ R.T + model.body_mass[b] * (r @ r * np.eye(3) - np.outer(r, r))
    return m.sum(), com, inertia


def _is_below(model, body, root):
    while body > 0:
        if body == root:
            return True
        body = model.body_parentid[body]
    return False


@pytest.mark.parametrize("variant", ["aof", "aff"])
def test_derived_feet_preserve_mass_com_and_foot_inertia(built, variant):
    """Computed here with MuJoCo's own quantities (subtree COM, body inertias), independently of
    the build's Pinocchio sums: mass and COM of the robot, each foot's centroidal inertia."""
    full, derived = _load(built, "full", "robot.xml"), _load(built, variant, "robot.xml")
    df, dd = mujoco.MjData(full), mujoco.MjData(derived)
    mujoco.mj_resetDataKeyframe(full, df, full.key("home").id)
    mujoco.mj_resetDataKeyframe(derived, dd, derived.key("home").id)
    dd.qpos[:7] = df.qpos[:7]  # same base pose (home heights differ by the touchdown points)
    mujoco.mj_kinematics(full, df), mujoco.mj_comPos(full, df)
    mujoco.mj_kinematics(derived, dd), mujoco.mj_comPos(derived, dd)
    assert mujoco.mj_getTotalmass(derived) == pytest.approx(mujoco.mj_getTotalmass(full), rel=1e-9)
    np.testing.assert_allclose(dd.subtree_com[1], df.subtree_com[1], rtol=0, atol=1e-9)
    for leg in C.LEGS:
        mf, cf, If = _foot_centroidal(full, df, f"{leg}_foot/mount")
        md, cd, Id = _foot_centroidal(derived, dd, f"{leg}_foot/mount")
        assert md == pytest.approx(mf, rel=1e-12)
        np.testing.assert_allclose(cd, cf, atol=1e-12)
        np.testing.assert_allclose(Id, If, atol=1e-9 * np.abs(If).max())
    # The report's own comparison agrees.
    assert built[variant][1]["mass_properties_vs_full"]["passed"]


@pytest.mark.parametrize("variant", ["full", "aof", "aff"])
def test_passive_dof_counts_and_sensors(built, variant):
    model = _load(built, variant, "robot.xml")
    per_foot = {"full": 31, "aof": 4, "aff": 2}[variant]
    assert model.nv == 6 + 12 + 4 * per_foot
    for leg in C.LEGS:
        foot_joints = [j for j in range(model.njnt) if model.joint(j).name.startswith(f"{leg}_foot/")]
        assert len(foot_joints) == per_foot
        for j in foot_joints:
            name = model.joint(j).name
            assert model.sensor(f"{name}_pos").type == mujoco.mjtSensor.mjSENS_JOINTPOS
            assert model.sensor(f"{name}_vel").type == mujoco.mjtSensor.mjSENS_JOINTVEL
        # The touchdown site: under the ankle, at the depth of the foot's lowest collision point
        # in the foot's root frame at the reference pose (qpos0).
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        site = model.site(f"{leg}_foot/touchdown")
        root = site.bodyid[0]
        bodies = [model.body(b).name for b in range(model.nbody) if model.body(b).name.startswith(f"{leg}_foot/")]
        local = (collision_points(model, data, bodies) - data.xpos[root]) @ data.xmat[root].reshape(3, 3)
        np.testing.assert_allclose(site.pos, [0.0, 0.0, local[:, 2].min()], atol=1e-9)
    # The IMU rides on the floating base.
    assert model.site("imu").bodyid[0] == model.jnt_bodyid[model.joint(C.FLOATING_JOINT).id]


def test_mjcf_on_disk_equals_model_in_memory(tmp_path):
    """dm_control's round trip: the written MJCF compiles to the same numbers as the model built."""
    from footforge.build import BuildOptions, build
    from footforge.mjcf import foot as foot_lib
    from footforge.mjcf.robot import build_robot

    out = tmp_path / "aof"
    build(BuildOptions(variant="aof", out_dir=out, cache_dir=tmp_path / "cache"))
    disk = mujoco.MjModel.from_xml_path(str(out / "robot.xml"))
    # Rebuild in memory from the same inputs.
    from footforge.inputs.description import default_foot_description
    from footforge.inputs.params import load_params
    from footforge.inputs.sidecar import default_sidecar_path, load_sidecar
    from footforge.mjcf.writing import compile_model
    from footforge.models import kinematics
    from footforge.models.collision import DecompositionConfig
    from footforge.models.foot_source import FootSource, decompose_collision_meshes
    from footforge.models.urdf import parse_urdf

    desc = load_description(default_foot_description())
    parsed = parse_urdf(desc, floating=True)
    sidecar = load_sidecar(default_sidecar_path(default_foot_description()))
    params = load_params()
    hulls = decompose_collision_meshes(parsed, DecompositionConfig(), cache_dir=tmp_path / "cache")
    source = FootSource(parsed, sidecar, params, kinematics.reference_pose(parsed, sidecar), hulls)
    robot = parse_urdf(load_description(default_robot_description(), args={"foot": "none"}), floating=True)
    memory = compile_model(
        build_robot(
            robot, foot_lib.build_derived(source, "aof"), variant="aof", params=params, friction=sidecar.friction
        ).mjcf
    )
    for field in (
        "body_mass",
        "body_inertia",
        "body_ipos",
        "body_iquat",
        "body_pos",
        "body_quat",
        "jnt_axis",
        "jnt_range",
        "jnt_stiffness",
        "dof_damping",
        "dof_armature",
        "geom_size",
        "geom_pos",
        "geom_quat",
        "actuator_gainprm",
        "actuator_biasprm",
        "key_qpos",
        "mesh_vert",
    ):
        np.testing.assert_array_equal(getattr(disk, field), getattr(memory, field), err_msg=field)


def test_pinocchio_and_mujoco_agree_on_mass_and_com(built):
    """The whole robot with SoftFoot-Q feet expanded from the ANYmal C xacro (foot:=softfoot_q) in
    Pinocchio, against the closed-chain MJCF footforge wrote, at the same pose."""
    desc = load_description(default_robot_description(), args={"foot": "softfoot_q"})
    from footforge.models.urdf import parse_urdf

    parsed = parse_urdf(desc, floating=True)
    model, data = parsed.model, parsed.model.createData()
    mj = _load(built, "full", "robot.xml")
    mjd = mujoco.MjData(mj)
    mujoco.mj_resetDataKeyframe(mj, mjd, mj.key("home").id)
    mujoco.mj_kinematics(mj, mjd), mujoco.mj_comPos(mj, mjd)
    q = pin.neutral(model)
    q[:3] = mjd.qpos[:3]
    for j in range(2, model.njoints):
        name = model.names[j]
        mj_name = name if name in C.ACTUATED_JOINTS else name.replace("_foot_", "_foot/", 1)
        q[model.joints[j].idx_q] = mjd.qpos[mj.jnt_qposadr[mj.joint(mj_name).id]]
    assert pin.computeTotalMass(model) == pytest.approx(mujoco.mj_getTotalmass(mj), rel=1e-12)
    np.testing.assert_allclose(pin.centerOfMass(model, data, q), mjd.subtree_com[1], atol=1e-9)
