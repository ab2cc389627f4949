"""Compiled MuJoCo model -> USD stage for Isaac Sim / Isaac Lab (UsdPhysics, usd-core only).

Stage: Z up, metres, kilograms, the model as the default prim with a physics scene. Bodies are
flat children of the default prim at the home pose (bodies.py), joints in a `joints` scope
(joints.py), geoms under their body (geoms.py). What USD cannot say is returned, by element,
instead of being dropped silently.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdPhysics

from footforge.models import massprops
from footforge.usd import bodies, geoms, joints
from footforge.usd.context import ExportContext, Unsupported


@dataclass
class Exported:
    stage: Usd.Stage
    unsupported: list[Unsupported] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def report(self) -> dict:
        return {"unsupported": [u.as_dict() for u in self.unsupported], "notes": list(self.notes)}


def export_model(model: mujoco.MjModel, *, name: str, keyframe: str | None = None) -> Exported:
    """Builds an in-memory stage for `model` posed at `keyframe` (default: qpos0).

    Args:
      model: the compiled model.
      name: the default prim's name (a valid USD identifier is made from it).
      keyframe: the pose the bodies are authored at; an engine reads initial joint angles from it.
    """
    data = massprops.at_keyframe(model, keyframe)
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, Sdf.Path.absoluteRootPath.AppendChild(Tf.MakeValidIdentifier(name)))
    stage.SetDefaultPrim(root.GetPrim())
    root.GetPrim().SetCustomDataByKey("footforge:source", "footforge build (from the compiled MJCF)")
    ctx = ExportContext(model, data, keyframe, stage, root.GetPath())
    _physics_scene(ctx)
    bodies.add_bodies(ctx)
    joint_paths = joints.add_joints(ctx)
    joints.add_equalities(ctx, joint_paths)
    geoms.add_geoms(ctx)
    bodies.add_sites(ctx)
    _articulation_roots(ctx, joint_paths)
    _report_model_level(ctx, keyframe)
    world = stage.GetPrimAtPath(ctx.body_paths[0])
    if not world.GetChildren():
        stage.RemovePrim(world.GetPath())
    return Exported(stage, ctx.unsupported, ctx.notes)


def _physics_scene(ctx: ExportContext) -> None:
    g = np.asarray(ctx.model.opt.gravity, float)
    scene = UsdPhysics.Scene.Define(ctx.stage, ctx.root.AppendChild("physics_scene"))
    magnitude = float(np.linalg.norm(g))
    direction = g / magnitude if magnitude else np.array([0.0, 0, -1])
    scene.CreateGravityDirectionAttr(Gf.Vec3f(*map(float, direction)))
    scene.CreateGravityMagnitudeAttr(magnitude)


def _articulation_roots(ctx: ExportContext, joint_paths: dict[int, Sdf.Path]) -> None:
    """ArticulationRootAPI on each floating base (a body with a free joint). A model without one
    (the drop rig: a carriage on a vertical slider) is a tree hung from the world; PhysX
    articulations attach to the world only rigidly, so the joints to the world are kept out of
    the articulation (simulated as ordinary joints) and the root goes on the bodies they carry."""
    m = ctx.model
    free = [int(m.jnt_bodyid[j]) for j in range(m.njnt) if int(m.jnt_type[j]) == mujoco.mjtJoint.mjJNT_FREE]
    for b in free:
        UsdPhysics.ArticulationRootAPI.Apply(ctx.stage.GetPrimAtPath(ctx.body_paths[b]))
    if free:
        return
    for j, path in joint_paths.items():
        b = int(m.jnt_bodyid[j])
        if m.body_weldid[m.body_parentid[b]] == 0:
            UsdPhysics.Joint(ctx.stage.GetPrimAtPath(path)).CreateExcludeFromArticulationAttr(True)
            UsdPhysics.ArticulationRootAPI.Apply(ctx.stage.GetPrimAtPath(ctx.body_paths[b]))
            ctx.notes.append(
                f"joint '{path.name}' to the world is excluded from the articulation "
                "(PhysX articulations attach to the world only through a fixed joint)"
            )


def _report_model_level(ctx: ExportContext, keyframe: str | None) -> None:
    m = ctx.model
    ctx.lose(
        "option",
        f"timestep {m.opt.timestep:g} s, {mujoco.mjtIntegrator(m.opt.integrator).name} integrator, "
        f"{mujoco.mjtSolver(m.opt.solver).name} solver, {m.opt.iterations} iterations",
        "dropped: set the Isaac Sim physics scene's own step and solver",
    )
    if m.nsensor:
        names = [m.sensor(s).name for s in range(m.nsensor)]
        ctx.lose(
            f"sensors ({m.nsensor})", ", ".join(names), "dropped: sites are exported as Xforms to attach sensors to"
        )
    if m.neq and any(int(m.eq_type[e]) == mujoco.mjtEq.mjEQ_CONNECT for e in range(m.neq)):
        ctx.notes.append(
            "loop closures are exported as hard spherical joints; MuJoCo's are soft "
            "(solref/solimp), so tiny closure gaps there are zero here"
        )
    keys = [m.key(k).name for k in range(m.nkey) if m.key(k).name != keyframe]
    if keys:
        ctx.lose(
            "keyframes",
            ", ".join(keys),
            "dropped: bodies are authored at the " + (f"'{keyframe}' keyframe" if keyframe else "reference pose"),
        )


def stage_files(stem: str) -> dict[str, str]:
    """The files one stage is written to, with their format: text and binary crate."""
    return {f"{stem}.usda": "usda", f"{stem}.usd": "usdc"}


def write_stage(stage: Usd.Stage, folder: Path, stem: str) -> list[str]:
    """Writes `<stem>.usda` (text) and `<stem>.usd` (binary crate); returns the file names."""
    names = stage_files(stem)
    for n, fmt in names.items():
        if not stage.GetRootLayer().Export(str(Path(folder) / n), args={"format": fmt}):
            raise OSError(f"could not write {Path(folder) / n}")
    return list(names)
