"""USD export: the written stages validate, and say the same physics as the compiled MJCF."""

import json
import math
import os
import shutil

import mujoco
import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdPhysics, UsdShade

from footforge import constants as C, units
from footforge.build import BuildOptions, build
from footforge.cli.main import main
from footforge.errors import CheckFailure
from footforge.inputs.params import load_params
from footforge.usd import (
    compare_with_model,
    comparison_failures,
    export_model,
    validate_stage,
)
from footforge.usd.checks import FLOAT32_RTOL
from footforge.usd.joints import axis_frame

from conftest import REPO

VARIANTS = ["full", "aof", "aff", "ball"]
MODELS = [("robot", "home"), ("foot_rig", "reference")]
GOLDEN = REPO / "tests/golden/ball_robot.usda"


def _model(built, variant, stem):
    return mujoco.MjModel.from_xml_path(str(built[variant][0] / f"{stem}.xml"))


def _stage(built, variant, stem, ext="usda"):
    return Usd.Stage.Open(str(built[variant][0] / f"{stem}.{ext}"))


STAGES = [
    # The closed chain's whole robot is the slowest stage (17 s of the default run's 6 minutes); the default
    # run's other tests read it too (text against binary, arch springs, loop closures); it runs as slow.
    pytest.param(variant, stem, key, marks=pytest.mark.slow)
    if (variant, stem) == ("full", "robot")
    else (variant, stem, key)
    for variant in VARIANTS
    for stem, key in MODELS
]


@pytest.mark.parametrize("variant,stem,key", STAGES)
@pytest.mark.parametrize("ext", ["usda", "usd"])
def test_written_stage_validates_and_matches_mjcf(built, variant, stem, key, ext):
    stage = _stage(built, variant, stem, ext)
    errors = [f for f in validate_stage(stage) if f["severity"] == "error"]
    assert not errors
    comparison = compare_with_model(stage, _model(built, variant, stem), keyframe=key)
    assert comparison_failures(comparison) == []
    # The schema stores 32-bit floats: what is read back is the MuJoCo value to float32 rounding.
    assert comparison["mass_rel"] <= 2 * FLOAT32_RTOL
    assert comparison["principal_inertia_rel"] <= 2 * FLOAT32_RTOL
    assert comparison["limit_rel"] <= 2 * FLOAT32_RTOL
    assert comparison["anchor_m"] <= 1e-6 and comparison["axis_rad"] <= 1e-6 and comparison["com_m"] <= 1e-6


def test_binary_and_text_files_hold_the_same_stage(built):
    a, b = _stage(built, "full", "robot", "usda"), _stage(built, "full", "robot", "usd")
    assert (built["full"][0] / "robot.usd").read_bytes()[:8] == b"PXR-USDC"  # the binary crate format
    paths_a = [str(p.GetPath()) for p in a.Traverse()]
    assert paths_a == [str(p.GetPath()) for p in b.Traverse()]
    for path in paths_a[::25]:
        for attr in a.GetPrimAtPath(path).GetAuthoredAttributes():
            assert attr.Get() == b.GetPrimAtPath(path).GetAttribute(attr.GetName()).Get(), (path, attr.GetName())


@pytest.mark.parametrize("variant", VARIANTS)
def test_stage_metadata_scene_and_articulation(built, variant):
    stage = _stage(built, variant, "robot")
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdPhysics.GetStageKilogramsPerUnit(stage) == 1.0
    root = stage.GetDefaultPrim()
    assert root.GetName() == "robot"
    scene = UsdPhysics.Scene(stage.GetPrimAtPath("/robot/physics_scene"))
    g = np.array(scene.GetGravityDirectionAttr().Get()) * scene.GetGravityMagnitudeAttr().Get()
    np.testing.assert_allclose(g, [0, 0, -9.81], rtol=1e-6)
    roots = [p for p in stage.Traverse() if p.HasAPI(UsdPhysics.ArticulationRootAPI)]
    assert [str(p.GetPath()) for p in roots] == ["/robot/base"]
    bodies = [p for p in stage.Traverse() if p.HasAPI(UsdPhysics.RigidBodyAPI)]
    for body in bodies:  # mass fully authored, never left to the engine
        mass = UsdPhysics.MassAPI(body)
        for attr in (
            mass.GetMassAttr(),
            mass.GetCenterOfMassAttr(),
            mass.GetDiagonalInertiaAttr(),
            mass.GetPrincipalAxesAttr(),
        ):
            assert attr.HasAuthoredValue(), (body.GetPath(), attr.GetName())
    total = sum(UsdPhysics.MassAPI(b).GetMassAttr().Get() for b in bodies)
    model = _model(built, variant, "robot")
    assert total == pytest.approx(mujoco.mj_getTotalmass(model), rel=len(bodies) * FLOAT32_RTOL)


def _joint(stage, name):
    for prim in stage.Traverse():
        if prim.GetCustomDataByKey("footforge:mjcfName") == name and prim.IsA(UsdPhysics.Joint):
            return prim
    raise KeyError(name)


@pytest.mark.parametrize("variant", VARIANTS)
def test_actuated_joints_carry_anymal_pd_gains_per_degree(built, variant):
    stage = _stage(built, variant, "robot")
    model = _model(built, variant, "robot")
    home = model.key("home").qpos
    for name in C.ACTUATED_JOINTS:
        drive = UsdPhysics.DriveAPI(_joint(stage, name), "angular")
        assert drive.GetStiffnessAttr().Get() == pytest.approx(C.KP_NM_PER_RAD * math.pi / 180, rel=FLOAT32_RTOL)
        assert drive.GetDampingAttr().Get() == pytest.approx(C.KD_NMS_PER_RAD * math.pi / 180, rel=FLOAT32_RTOL)
        assert drive.GetMaxForceAttr().Get() == pytest.approx(C.EFFORT_LIMIT_NM)
        target_rad = units.deg_to_rad(drive.GetTargetPositionAttr().Get())
        assert target_rad == pytest.approx(home[model.jnt_qposadr[model.joint(name).id]], abs=1e-6)


def test_aof_passive_joints_are_sprung_drives_with_zero_target(built):
    stage = _stage(built, "aof", "robot")
    params = load_params().aof
    for leg in C.LEGS:
        for joint, p in params.items():
            prim = _joint(stage, f"{C.FOOT_MODEL_NAME.format(leg=leg)}/{joint}")
            drive = UsdPhysics.DriveAPI(prim, "angular")
            assert units.gain_per_rad(drive.GetStiffnessAttr().Get()) == pytest.approx(p.stiffness, rel=FLOAT32_RTOL)
            assert units.gain_per_rad(drive.GetDampingAttr().Get()) == pytest.approx(p.damping, rel=FLOAT32_RTOL)
            assert drive.GetTargetPositionAttr().Get() == pytest.approx(0.0, abs=1e-9)
            assert not drive.GetMaxForceAttr().HasAuthoredValue()


def test_arch_spring_drives_give_the_tendon_torque_along_the_tendon(built):
    """MuJoCo's own passive force of the arch band, against the exported per-joint drives, at
    the home pose and after both arches bend by a further 0.1 rad (the band's stretching mode)."""
    model = _model(built, "full", "robot")
    stage = _stage(built, "full", "robot")
    data = mujoco.MjData(model)
    joints = [f"LF_foot/{j}" for j in ("front_arch", "back_arch")]
    adr = [model.jnt_qposadr[model.joint(j).id] for j in joints]
    dof = [model.jnt_dofadr[model.joint(j).id] for j in joints]
    drives = [UsdPhysics.DriveAPI(_joint(stage, j), "angular") for j in joints]
    for bend in (0.0, 0.1):
        mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
        data.qpos[adr] += bend
        mujoco.mj_forward(model, data)
        for i, drive in enumerate(drives):
            k = units.gain_per_rad(drive.GetStiffnessAttr().Get())
            target = units.deg_to_rad(drive.GetTargetPositionAttr().Get())
            # A USD joint's angle is zero at qpos0 (the joint's `ref`: the closed chain is authored
            # at its reference pose).
            usd_torque = -k * (data.qpos[adr[i]] - model.qpos0[adr[i]] - target)
            assert usd_torque == pytest.approx(data.qfrc_spring[dof[i]], abs=1e-6)


def test_closed_chain_loops_and_coupling(built):
    stage = _stage(built, "full", "robot")
    _, report = built["full"]
    closures = [p for p in stage.Traverse() if p.IsA(UsdPhysics.SphericalJoint)]
    assert len(closures) == 4 * 3
    for prim in closures:
        assert UsdPhysics.Joint(prim).GetExcludeFromArticulationAttr().Get() is True
    back_roll = _joint(stage, "LF_foot/back_roll")
    assert list(back_roll.GetCustomDataByKey("footforge:couplingPolycoef"))[:2] == [0.0, -1.0]
    unsupported = report["usd"]["robot"]["unsupported"]
    elements = {u["element"] for u in unsupported}
    for leg in C.LEGS:  # nothing silently lost: the coupling, the tendon, joint friction
        assert f"equality '{leg}_foot/couple_back_roll'" in elements
        assert f"tendon '{leg}_foot/arch_spring'" in elements
        assert f"joint '{leg}_foot/front_arch'" in elements
    model = _model(built, "full", "robot")
    with_friction = {model.joint(j).name for j in range(model.njnt) if model.dof_frictionloss[model.jnt_dofadr[j]]}
    assert with_friction <= {e.split("'")[1] for e in elements if e.startswith("joint '")}


@pytest.mark.parametrize("variant", VARIANTS)
def test_colliders_and_visuals(built, variant):
    stage = _stage(built, variant, "robot")
    model = _model(built, variant, "robot")
    colliders = [p for p in stage.Traverse() if p.HasAPI(UsdPhysics.CollisionAPI)]
    n_colliders = sum(bool(model.geom_contype[g] or model.geom_conaffinity[g]) for g in range(model.ngeom))
    assert len(colliders) == n_colliders
    frictions = set()
    for prim in colliders:
        assert "/collisions/" in str(prim.GetPath())
        if prim.IsA(UsdGeom.Mesh):
            assert UsdPhysics.MeshCollisionAPI(prim).GetApproximationAttr().Get() == UsdPhysics.Tokens.convexHull
            assert len(UsdGeom.Mesh(prim).GetPointsAttr().Get()) <= 64
        else:
            assert prim.GetTypeName() in ("Cube", "Sphere", "Cylinder", "Capsule", "Plane")
        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial("physics")
        frictions.add(round(UsdPhysics.MaterialAPI(material.GetPrim()).GetStaticFrictionAttr().Get(), 6))
    assert frictions == {
        round(float(f), 6) for f in model.geom_friction[:, 0][(model.geom_contype > 0) | (model.geom_conaffinity > 0)]
    }
    visuals = [p for p in stage.Traverse() if "/visuals/" in str(p.GetPath())]
    assert visuals and not any(p.HasAPI(UsdPhysics.CollisionAPI) for p in visuals)
    if variant == "full":  # the CoACD hulls of the chain, each its own convex mesh
        assert sum(p.IsA(UsdGeom.Mesh) for p in colliders) == sum(
            model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH and model.geom_conaffinity[g] for g in range(model.ngeom)
        )


def test_axis_frames_rotate_the_token_axis_onto_the_joint_axis():
    rng = np.random.default_rng(0)
    for axis in [np.array([0, 0, 1.0]), np.array([-1.0, 0, 0]), *rng.normal(size=(20, 3))]:
        token, quat = axis_frame(axis)
        rotated = np.zeros(3)
        mujoco.mju_rotVecQuat(rotated, {"X": [1.0, 0, 0], "Y": [0, 1.0, 0], "Z": [0, 0, 1.0]}[token], quat)
        np.testing.assert_allclose(rotated, axis / np.linalg.norm(axis), atol=1e-12)


def _structure(stage):
    """Every prim: type, applied schemas, custom data, authored values and relationship targets."""

    def value(v):
        if isinstance(v, str) or not hasattr(v, "__len__"):
            return v if isinstance(v, (bool, int, float)) else str(v)
        return [value(x) for x in v]

    out = {}
    for prim in stage.Traverse():
        out[str(prim.GetPath())] = {
            "type": prim.GetTypeName(),
            "schemas": list(prim.GetAppliedSchemas()),
            "customData": str(prim.GetCustomData()),
            "attributes": {a.GetName(): value(a.Get()) for a in prim.GetAuthoredAttributes()},
            "relationships": {r.GetName(): [str(t) for t in r.GetTargets()] for r in prim.GetAuthoredRelationships()},
        }
    return out


def _same(a, b, where):
    if isinstance(a, float) or isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-6, abs=1e-12), where
    elif isinstance(a, (list, dict)):
        assert type(a) is type(b) and len(a) == len(b), where
        for key in a if isinstance(a, dict) else range(len(a)):
            _same(a[key], b[key], f"{where}/{key}")
    else:
        assert a == b, where


def test_ball_robot_matches_the_golden_stage(built):
    """tests/golden/ball_robot.usda is the reviewed ball-foot export, compared prim by prim and
    value by value (relative 1e-6). Regenerate it with FOOTFORGE_UPDATE_GOLDEN=1 and read the diff."""
    written = built["ball"][0] / "robot.usda"
    if os.environ.get("FOOTFORGE_UPDATE_GOLDEN"):
        shutil.copy(written, GOLDEN)
    golden, got = _structure(Usd.Stage.Open(str(GOLDEN))), _structure(Usd.Stage.Open(str(written)))
    assert sorted(got) == sorted(golden)
    for path in golden:
        _same(got[path], golden[path], path)


def test_foot_only_build_exports_the_foot(tmp_path):
    out = tmp_path / "foot"
    report = build(BuildOptions(variant="aof", out_dir=out, foot_only=True, formats=("usd",)))
    stage = Usd.Stage.Open(str(out / "foot.usda"))
    assert not [f for f in validate_stage(stage) if f["severity"] == "error"]
    assert report["usd"]["foot"]["vs_mjcf"]["joint_counts"]["usd"] == {"RevoluteJoint": 4}
    assert sorted(report["usd"]) == ["foot", "foot_rig"]


def test_broken_stage_fails_validation_with_exit_1(tmp_path, monkeypatch):
    """An export that does not validate makes the build fail (exit 1) and write nothing."""
    from footforge import usd

    real = usd.export_model

    def broken(model, **kw):
        exported = real(model, **kw)
        joint = UsdPhysics.RevoluteJoint.Define(exported.stage, "/robot/joints/dangling")
        joint.CreateBody1Rel().SetTargets(["/robot/no_such_body"])
        return exported

    monkeypatch.setattr(usd, "export_model", broken)
    out = tmp_path / "out"
    with pytest.raises(CheckFailure, match="JointInvalidPrimRel"):
        build(BuildOptions(variant="ball", out_dir=out))
    assert not out.exists()
    assert main(["build", "--variant", "ball", "--out", str(out)]) == 1


def test_format_selects_outputs(tmp_path):
    usd_only, mjcf_only = tmp_path / "usd", tmp_path / "mjcf"
    assert main(["build", "--variant", "ball", "--format", "usd", "--out", str(usd_only)]) == 0
    assert sorted(p.name for p in usd_only.iterdir()) == sorted(
        ["robot.usda", "robot.usd", "foot_rig.usda", "foot_rig.usd", "build_report.json", ".footforge-output"]
    )
    assert main(["build", "--variant", "ball", "--format", "mjcf", "--out", str(mjcf_only)]) == 0
    names = {p.name for p in mjcf_only.iterdir()}
    assert "robot.xml" in names and not any(n.endswith((".usd", ".usda")) for n in names)
    assert "usd" not in json.loads((mjcf_only / "build_report.json").read_text())


def test_unknown_format_is_a_usage_error(tmp_path, capsys):
    assert main(["build", "--variant", "ball", "--format", "fbx", "--out", str(tmp_path / "x")]) == 2
    assert "unknown output format 'fbx'" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_export_is_deterministic(built):
    model = _model(built, "aof", "robot")
    first, second = (export_model(model, name="robot", keyframe="home") for _ in range(2))
    assert first.stage.GetRootLayer().ExportToString() == second.stage.GetRootLayer().ExportToString()


def test_unsupported_constructs_are_named_not_dropped_silently():
    """A model with constructs UsdPhysics lacks: each is reported by element, and the stage
    still validates."""
    xml = """<mujoco>
      <worldbody>
        <body name="a" pos="0 0 1">
          <freejoint/>
          <geom name="egg" type="ellipsoid" size=".1 .2 .3"/>
          <body name="b" pos="0 0 -.5">
            <joint name="j1" axis="0 1 1" frictionloss="0.2"/>
            <joint name="j2" axis="1 0 0"/>
            <geom name="box" type="box" size=".1 .1 .1"/>
          </body>
        </body>
      </worldbody>
      <sensor><framepos name="p" objtype="body" objname="a"/></sensor>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    exported = export_model(model, name="odd")
    elements = {u.element: u for u in exported.unsupported}
    assert "geom type mjGEOM_ELLIPSOID" in elements["geom 'egg'"].feature
    assert "2 joints on one body" in elements["body 'b'"].feature
    assert "dry friction 0.2" in elements["joint 'j1'"].feature
    assert "sensors (1)" in elements
    assert not [f for f in validate_stage(exported.stage) if f["severity"] == "error"]
    token, _ = axis_frame(model.jnt_axis[1])
    assert token == "X"  # a skew axis: the joint frame is rotated instead


def test_unnamed_bodies_motors_and_clashing_names_export_cleanly():
    """An unnamed body, a body called like a footforge scope, a motor (not a servo): the stage
    validates and matches the model; the motor is reported, not counted as a drive."""
    xml = """<mujoco>
      <worldbody>
        <body name="joints" pos="0 0 1">
          <freejoint/>
          <geom type="box" size=".1 .1 .1"/>
          <body pos="0 0 -.3">
            <joint name="h" axis="0 1 0" range="-1 1"/>
            <geom type="capsule" size=".02 .1"/>
          </body>
        </body>
      </worldbody>
      <actuator><motor joint="h"/></actuator>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    exported = export_model(model, name="odd")
    assert not [f for f in validate_stage(exported.stage) if f["severity"] == "error"]
    assert comparison_failures(compare_with_model(exported.stage, model)) == []
    assert any(u.element == "actuator 'actuator_0'" for u in exported.unsupported)
