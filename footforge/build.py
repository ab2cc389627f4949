"""`footforge build`: description -> MJCF models of ANYmal C with a foot variant, checked.

Outputs (in `out_dir`, written to a temporary folder first and renamed, never half-written):
- format mjcf: robot.xml, scene.xml, foot_rig.xml (or foot.xml and foot_rig.xml with
  `foot_only`) and assets/;
- format usd: robot.usda and robot.usd (binary), foot_rig.usda/.usd (foot.usda/.usd), exported
  from the compiled MJCF models, validated by usd-core and compared with them;
- always build_report.json.
The default is both formats: the USD export costs a fraction of a second per model.
"""

from __future__ import annotations

import difflib
import hashlib
import json
import platform
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, Literal, Mapping

import mujoco
import numpy as np
from dm_control import mjcf
from lxml import etree

from footforge import constants as C
from footforge import foot as foot_lib
from footforge import kinematics, massprops
from footforge.atomic import atomic_directory
from footforge.collision import DecompositionConfig
from footforge.description import (Description, default_foot_description, default_robot_description,
                                   load_description)
from footforge.errors import CheckFailure, InputError
from footforge.outputs import check_output_folder
from footforge.params import VariantParams, load_params
from footforge.robot import build_rig, build_robot, scene_xml
from footforge.foot_root import select_foot_root
from footforge.sidecar import Sidecar, find_sidecar, load_sidecar
from footforge.urdf_check import Finding, check_urdf, format_findings, has_errors, repair_urdf
from footforge.urdf_import import parse_urdf

VARIANTS = ("full", "aof", "aff", "ball")
Variant = Literal["full", "aof", "aff", "ball"]
FORMATS = ("mjcf", "usd")

MASS_RTOL = 1e-9
"""Total mass and centre of mass of aff/aof must equal the closed chain's to this (relative)."""
INERTIA_RTOL = 1e-9
"""Each foot's centroidal inertia likewise (relative, Frobenius norm)."""
REPORT_FORMAT = C.BUILD_FORMAT
INPUT_ERROR_CODES = frozenset({"missing_mesh", "unresolved_package"})


@dataclass(frozen=True)
class BuildOptions:
    variant: Variant
    """Which feet: full (closed chain), aof, aff, ball."""
    out_dir: Path
    """Output folder; replaced as a whole when the build succeeds (if new, empty, or written by
    footforge: footforge.outputs)."""
    force: bool = False
    """Replace `out_dir` even if footforge did not write it (the user's --force)."""
    foot_only: bool = False
    """Write the foot alone (foot.xml) and its rig, no robot."""
    foot_description: Path | None = None
    """Foot xacro/URDF; default descriptions/softfoot_q/urdf/softfoot_q.urdf.xacro."""
    sidecar: Path | None = None
    """Foot sidecar; default <stem>.sidecar.yaml beside the foot description."""
    robot_description: Path | None = None
    """Robot xacro/URDF with a `foot` argument (ball|none); default ANYmal C."""
    package_paths: tuple[Path, ...] = ()
    """Folders searched for ROS packages before ROS_PACKAGE_PATH and the project's own."""
    foot_args: Mapping[str, str] = field(default_factory=dict)
    """xacro arguments for the foot description."""
    params: Path | None = None
    """Variant parameter file; default descriptions/softfoot_q/config/variant_params.yaml."""
    repair: bool = False
    """Repair the descriptions' repairable defects (reported) instead of refusing them."""
    decomposition: DecompositionConfig = DecompositionConfig()
    cache_dir: Path | None = None
    """CoACD cache; default ~/.cache/footforge/coacd (or $FOOTFORGE_CACHE)."""
    formats: tuple[str, ...] = FORMATS
    """Which outputs: "mjcf" (MuJoCo XML and assets) and/or "usd" (for Isaac Sim)."""


class Stages:
    """Timings and a progress callback per stage."""

    def __init__(self, progress: Callable[[str], None] | None):
        self.progress = progress or (lambda msg: None)
        self.timings_s: dict[str, float] = {}

    @contextmanager
    def __call__(self, name: str):
        self.progress(name)
        t0 = time.perf_counter()
        yield
        self.timings_s[name] = round(time.perf_counter() - t0, 4)


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def checked_description(description: Description, *, repair: bool, what: str) -> tuple[Description, list[Finding], list[str]]:
    """Runs `check` on a description; repairs it if asked; refuses one with errors.

    Raises:
      CheckFailure: errors remain (all of them are listed, with fixes).
    """
    findings = check_urdf(description.root(), resolve_uri=description.resolve_uri)
    notes: list[str] = []
    if has_errors(findings) and repair:
        repaired, notes = repair_urdf(description.root(), findings)
        description = replace(description, urdf=etree.tostring(repaired, encoding="unicode"))
        findings = check_urdf(description.root(), resolve_uri=description.resolve_uri)
    missing = [f for f in findings if f.severity == "error" and f.code in INPUT_ERROR_CODES]
    if missing:  # files that are not there are input errors (exit 2), not model defects
        raise InputError(f"the {what} description refers to files it cannot find:\n{format_findings(missing)}",
                         file=str(description.source),
                         fix="fix the paths, or add the folder holding the package with --package-path")
    if has_errors(findings):
        repairable = all(f.repairable for f in findings if f.severity == "error")
        raise CheckFailure(
            f"the {what} description has errors:\n{format_findings([f for f in findings if f.severity == 'error'])}",
            file=str(description.source),
            fix=("rerun with --repair to apply the listed repairs (recorded in the build report)"
                 if repairable else "fix the description as suggested above"))
    return description, findings, notes


def link_inertia_checks(description: Description, findings: list[Finding]) -> dict[str, str]:
    """Per link with an inertial: 'ok' or the codes of its inertia findings."""
    by_link: dict[str, list[str]] = {}
    for f in findings:
        if f.element.startswith("link '"):
            by_link.setdefault(f.element.split("'")[1], []).append(f.code)
    out = {}
    for link in description.root().findall("link"):
        if link.find("inertial") is not None:
            codes = by_link.get(link.get("name"), [])
            out[link.get("name")] = "ok" if not codes else ", ".join(codes)
    return out


def model_counts(model: mujoco.MjModel) -> dict:
    kinds = {int(mujoco.mjtJoint.mjJNT_FREE): "free", int(mujoco.mjtJoint.mjJNT_BALL): "ball",
             int(mujoco.mjtJoint.mjJNT_SLIDE): "slide", int(mujoco.mjtJoint.mjJNT_HINGE): "hinge"}
    by_kind: dict[str, int] = {}
    for t in model.jnt_type:
        by_kind[kinds[int(t)]] = by_kind.get(kinds[int(t)], 0) + 1
    eq_kinds = {int(mujoco.mjtEq.mjEQ_CONNECT): "connect", int(mujoco.mjtEq.mjEQ_WELD): "weld",
                int(mujoco.mjtEq.mjEQ_JOINT): "joint", int(mujoco.mjtEq.mjEQ_TENDON): "tendon"}
    eqs: dict[str, int] = {}
    for t in model.eq_type:
        eqs[eq_kinds.get(int(t), str(int(t)))] = eqs.get(eq_kinds.get(int(t), str(int(t))), 0) + 1
    return {"bodies": int(model.nbody - 1), "joints_by_kind": by_kind, "nq": int(model.nq),
            "dof": int(model.nv), "actuators": int(model.nu), "sensors": int(model.nsensor),
            "equality_constraints": eqs, "tendons": int(model.ntendon),
            "geoms": int(model.ngeom), "mesh_assets": int(model.nmesh),
            "total_mass_kg": float(mujoco.mj_getTotalmass(model)), "timestep_s": float(model.opt.timestep)}


def closure_gaps(model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, float]:
    """Distance between the two sites of every closure equality (m)."""
    gaps = {}
    for e in range(model.neq):
        if model.eq_type[e] == mujoco.mjtEq.mjEQ_CONNECT and model.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
            a, b = model.eq_obj1id[e], model.eq_obj2id[e]
            gaps[model.eq(e).name] = float(np.linalg.norm(data.site_xpos[a] - data.site_xpos[b]))
    return gaps


def compare_mass_properties(variant_model: mujoco.MjModel, full_model: mujoco.MjModel, key: str,
                            foot_roots: list[str]) -> dict:
    """Total mass, centre of mass and each foot's centroidal inertia, variant against full, with
    the base of both at the closed-chain model's keyframe pose (the home heights differ by the
    feet's touchdown points)."""
    df = massprops.at_keyframe(full_model, key)
    dv = massprops.at_keyframe(variant_model, key, free_joint_qpos=df.qpos[:7])
    tv, tf = massprops.subtree_inertia(variant_model, dv, 0), massprops.subtree_inertia(full_model, df, 0)
    scale = max(float(np.linalg.norm(tf.lever)), 1.0)
    report = {
        "total_mass": {"variant_kg": tv.mass, "full_kg": tf.mass,
                       "relative_error": abs(tv.mass - tf.mass) / tf.mass, "tolerance": MASS_RTOL},
        "com": {"variant_m": np.array(tv.lever).tolist(), "full_m": np.array(tf.lever).tolist(),
                "relative_error": float(np.linalg.norm(tv.lever - tf.lever)) / scale, "tolerance": MASS_RTOL},
        "feet": {},
    }
    for body in foot_roots:
        fv = massprops.subtree_inertia(variant_model, dv, variant_model.body(body).id)
        ff = massprops.subtree_inertia(full_model, df, full_model.body(body).id)
        report["feet"][body] = {
            "mass_relative_error": abs(fv.mass - ff.mass) / ff.mass,
            "com_error_m": float(np.linalg.norm(fv.lever - ff.lever)),
            "centroidal_inertia_relative_error": float(np.linalg.norm(fv.inertia - ff.inertia) / np.linalg.norm(ff.inertia)),
            "tolerance": INERTIA_RTOL}
    errs = [report["total_mass"]["relative_error"], report["com"]["relative_error"]] + [
        max(f["mass_relative_error"], f["com_error_m"] / scale, f["centroidal_inertia_relative_error"])
        for f in report["feet"].values()]
    report["passed"] = bool(max(errs) <= MASS_RTOL)
    return report


def build(options: BuildOptions, *, progress: Callable[[str], None] | None = None) -> dict:
    """Builds the models of `options.variant` and writes them to `options.out_dir`.

    Returns:
      The build report (also written as build_report.json).

    Raises:
      InputError: bad input (missing files, malformed descriptions, unknown names); exit 2.
      CheckFailure: a description or model check failed; exit 1.
    """
    if options.variant not in VARIANTS:
        raise InputError(f"unknown variant '{options.variant}'", fix=f"use one of {', '.join(VARIANTS)}")
    unknown = [f for f in options.formats if f not in FORMATS]
    if unknown or not options.formats:
        raise InputError(f"unknown output format '{', '.join(unknown)}'" if unknown else "no output format given",
                         fix=f"use one or more of {', '.join(FORMATS)}, e.g. --format mjcf,usd")
    check_output_folder(options.out_dir, force=options.force)  # before minutes of CoACD
    stage = Stages(progress)
    report: dict = {"format": REPORT_FORMAT, "variant": options.variant, "foot_only": options.foot_only,
                    "versions": versions(), "machine": platform.platform(), "repairs": [], "warnings": []}
    params = load_params(options.params)
    report["inputs"] = {"params": {"path": str(params.source), "sha256": _sha256(params.source)}}
    files: dict[str, str] = {}
    asset_sets: list[dict] = []
    stages: dict[str, object] = {}
    if "usd" in options.formats:
        report["usd"] = {}

    foot = full_foot = None
    sidecar = None
    if options.variant != "ball":
        source = load_foot_source(options, stage, report, params)
        sidecar = source.sidecar
        with stage(f"build {options.variant} foot"):
            full_foot = foot_lib.build_full(source)
            foot = full_foot if options.variant == "full" else foot_lib.build_derived(source, options.variant, full=full_foot)
            report["foot"] = foot.info | {"passive_joints": foot.passive_joints,
                                          "reference_qpos_rad": foot.reference_qpos,
                                          "touchdown_m": foot.touchdown.tolist()}

    friction = sidecar.friction if sidecar else 0.8
    with stage("build rig"):
        rig = build_rig(foot, C.BALL_FOOT_RADIUS_M, variant=options.variant, params=params, friction=friction)
        files["foot_rig.xml"] = _xml(rig.mjcf, asset_sets)
        rig_model = foot_lib.compile_model(rig.mjcf)
        report["foot_rig"] = model_counts(rig_model) | {"payload_kg": params.rig_payload_mass}
    _export_usd(options, stage, report, stages, "foot_rig", rig_model, "reference")

    if options.foot_only:
        if foot is None:
            raise InputError("--foot-only needs an adaptive foot variant", fix="use --variant full, aof or aff")
        with stage("write foot model"):
            files["foot.xml"] = _xml(foot.mjcf, asset_sets)
            foot_model = foot_lib.compile_model(foot.mjcf)
            report["model"] = model_counts(foot_model)
        _export_usd(options, stage, report, stages, "foot", foot_model, None)
    else:
        with stage("build robot"):
            robot_path = Path(options.robot_description or default_robot_description())
            foot_arg = "ball" if options.variant == "ball" else "none"
            robot_desc = load_description(robot_path, args={"foot": foot_arg}, package_paths=options.package_paths)
            robot_desc, robot_findings, notes = checked_description(robot_desc, repair=options.repair, what="robot")
            report["repairs"] += [f"{robot_path.name}: {n}" for n in notes]
            report["inputs"]["robot_description"] = {"path": str(robot_desc.source), "sha256": _sha256(robot_desc.source),
                                                     "args": {"foot": foot_arg}}
            report.setdefault("link_inertia_checks", {})["robot"] = link_inertia_checks(robot_desc, robot_findings)
            robot_parsed = parse_urdf(robot_desc, floating=True)
            robot = build_robot(robot_parsed, foot, variant=options.variant, params=params, friction=friction)
            files["robot.xml"] = _xml(robot.mjcf, asset_sets)
            files["scene.xml"] = scene_xml("robot.xml", options.variant)
            robot_model = foot_lib.compile_model(robot.mjcf)
            report["model"] = model_counts(robot_model)
            report["model"]["home_base_height_m"] = float(robot_model.key("home").qpos[2])
        _export_usd(options, stage, report, stages, "robot", robot_model, "home")
        if options.variant == "full":
            with stage("check closures"):
                data = massprops.at_keyframe(robot_model, "home")
                gaps = closure_gaps(robot_model, data)
                report["closure_residual_at_home_m"] = max(gaps.values())
        elif options.variant in ("aof", "aff"):
            with stage("compare mass properties"):
                full_robot = build_robot(robot_parsed, full_foot, variant="full", params=params, friction=friction,
                                         stand_keyframe=False)
                full_model = foot_lib.compile_model(full_robot.mjcf)
                roots = [f"{C.FOOT_MODEL_NAME.format(leg=leg)}/{foot.root_body}" for leg in C.LEGS]
                comparison = compare_mass_properties(robot_model, full_model, "home", roots)
                report["mass_properties_vs_full"] = comparison
    report["timings_s"] = stage.timings_s
    if "mass_properties_vs_full" in report and not report["mass_properties_vs_full"]["passed"]:
        raise CheckFailure("mass properties of the derived feet differ from the closed chain's beyond "
                           f"{MASS_RTOL:g}: {json.dumps(report['mass_properties_vs_full'])}",
                           fix="report this as a bug: derived bodies must be exact composites")
    if "mjcf" not in options.formats:
        files, asset_sets = {}, []
    _write_atomically(options.out_dir, files, asset_sets, report, stages, force=options.force)
    return report


def _export_usd(options: BuildOptions, stage: Stages, report: dict, stages: dict, stem: str,
                model: mujoco.MjModel, keyframe: str | None) -> None:
    """Exports one compiled model to USD, validates it and compares it with the model.

    Raises:
      CheckFailure: usd-core's validators report errors, or the stage differs from the model.
    """
    if "usd" not in options.formats:
        return
    from footforge import usd

    with stage(f"export {stem} to USD"):
        exported = usd.export_model(model, name=stem, keyframe=keyframe)
        findings = usd.validate_stage(exported.stage)
        comparison = usd.compare_with_model(exported.stage, model, keyframe=keyframe)
    errors = [f for f in findings if f["severity"] == "error"]
    report["usd"][stem] = {"files": list(usd.stage_files(stem)), "keyframe": keyframe,
                           "validation": findings, "vs_mjcf": comparison, "tolerances": usd.TOLERANCES,
                           **exported.report()}
    if errors:
        raise CheckFailure(f"the exported {stem} USD stage fails usd-core's validation:\n" + "\n".join(
            f"  {e['name']}: {e['message']} ({', '.join(e['prims'])})" for e in errors),
            fix="report this as a bug in footforge's USD exporter; use --format mjcf meanwhile")
    failures = usd.comparison_failures(comparison)
    if failures:
        raise CheckFailure(f"the exported {stem} USD stage differs from its MJCF model:\n  " + "\n  ".join(failures),
                           fix="report this as a bug in footforge's USD exporter; use --format mjcf meanwhile")
    stages[stem] = exported.stage


def load_foot_source(options: BuildOptions, stage: Stages, report: dict,
                     params: VariantParams | None = None) -> foot_lib.FootSource:
    """Reads and checks the foot description and its sidecar, solves the reference pose and
    decomposes the collision meshes: everything every foot variant is built from.

    `params` are the already loaded options.params, if the caller has them.

    Raises:
      InputError, CheckFailure: as `build`.
    """
    params = params or load_params(options.params)
    with stage("read foot description"):
        path = Path(options.foot_description or default_foot_description())
        description = load_description(path, args=options.foot_args, package_paths=options.package_paths)
        sidecar = load_sidecar(Path(options.sidecar) if options.sidecar else find_sidecar(path))
        # The foot alone: a test rig's `world` and leg above the foot's root link are dropped
        # before the checks, which then speak of the foot only.
        description, root_notes = select_foot_root(description, sidecar.root_link, sidecar_path=sidecar.source)
        report.setdefault("repairs", []).extend(f"{path.name}: {n}" for n in root_notes)
        description, findings, notes = checked_description(description, repair=options.repair, what="foot")
        report.setdefault("repairs", []).extend(f"{path.name}: {n}" for n in notes)
        report.setdefault("warnings", []).extend(f"{path.name}: {f.element}: {f.message}" for f in findings)
        inputs = report.setdefault("inputs", {})
        inputs["foot_description"] = {"path": str(description.source), "sha256": _sha256(description.source),
                                      "args": dict(options.foot_args)}
        inputs["sidecar"] = {"path": str(sidecar.source), "sha256": _sha256(sidecar.source)}
        report["link_inertia_checks"] = {"foot": link_inertia_checks(description, findings)}
        parsed = parse_urdf(description, floating=True)
        _check_sidecar_names(parsed, sidecar)
    with stage("solve reference pose"):
        reference = kinematics.reference_pose(parsed, sidecar)
    with stage("decompose collision meshes"):
        hull_report = []
        started_s = [0.0]

        def starting(mesh, i, n):
            started_s[0] = time.perf_counter()
            stage.progress(f"decompose collision meshes: {i}/{n} {Path(mesh).name}")

        hulls = foot_lib.decompose_collision_meshes(
            parsed, options.decomposition, cache_dir=options.cache_dir, starting=starting,
            progress=lambda mesh, h: hull_report.append(
                {"mesh": str(mesh), "hulls": len(h.vertices), "vertices": [len(v) for v in h.vertices],
                 "decomposed": h.decomposed, "cached": h.cached,
                 "seconds": round(time.perf_counter() - started_s[0], 3)}))
        report["collision"] = {"config": asdict(options.decomposition), "meshes": hull_report}
    return foot_lib.FootSource(parsed, sidecar, params, reference, hulls)


def _check_sidecar_names(parsed, sidecar: Sidecar) -> None:
    """Every joint and link the sidecar names must be in the description: a typo is the sidecar's,
    so the message names the sidecar file and the key to edit, and the closest names."""
    wanted: list[tuple[str, str, str]] = [(f"arch_joints[{i}]", "joint", n) for i, n in enumerate(sidecar.arch_joints)]
    wanted += [("roll_joints.front", "joint", sidecar.roll_front), ("roll_joints.back", "joint", sidecar.roll_back)]
    if sidecar.roll_coupling:
        wanted += [("roll_coupling.joint", "joint", sidecar.roll_coupling.joint),
                   ("roll_coupling.follows", "joint", sidecar.roll_coupling.follows)]
    if sidecar.arch_spring:
        wanted += [("arch_spring.joints", "joint", n) for n in sidecar.arch_spring.joints]
    wanted += [("reference_pose.joints", "joint", n) for n in sidecar.reference_joints]
    for i, c in enumerate(sidecar.closures):
        wanted += [(f"closures[{i}].link", "link", c.link), (f"closures[{i}].to_link", "link", c.to_link)]
    root = parsed.description.root()
    names = {"joint": [j.get("name") for j in root.findall("joint")],
             "link": [l.get("name") for l in root.findall("link")]}
    unknown = [(key, kind, name) for key, kind, name in wanted if name not in names[kind]]
    if unknown:
        lines = []
        for key, kind, name in unknown:
            near = difflib.get_close_matches(name, names[kind], n=2, cutoff=0.5)
            lines.append(f"  {key}: {kind} '{name}' is not in the description"
                         + (f" (closest: {', '.join(near)})" if near else ""))
        raise InputError(
            f"the sidecar names {len(unknown)} joint(s)/link(s) that {parsed.description.source.name} "
            "does not have:\n" + "\n".join(lines),
            file=str(sidecar.source), element=unknown[0][0],
            fix=f"edit those keys in {sidecar.source} to the description's names as expanded "
                "(with the macro's prefix, if any), or pass the right sidecar with --sidecar")


def _xml(root: mjcf.RootElement, asset_sets: list[dict]) -> str:
    """MJCF text whose asset files (content-hashed names from dm_control) live in assets/."""
    tree = etree.fromstring(root.to_xml_string().encode())
    compiler = tree.find("compiler")
    if compiler is None:
        compiler = etree.Element("compiler")
        tree.insert(0, compiler)
    # dm_control resolves asset paths itself and does not write meshdir; MuJoCo needs it on disk.
    compiler.set("meshdir", "assets")
    compiler.set("texturedir", "assets")
    asset_sets.append(root.get_assets())
    return etree.tostring(tree, pretty_print=True, encoding="unicode")


def _write_atomically(out_dir: Path, files: dict[str, str], asset_sets: list[dict], report: dict,
                      stages: Mapping[str, object] = {}, *, force: bool = False) -> None:
    with atomic_directory(out_dir, force=force) as tmp:
        outputs = sorted(files)
        if asset_sets:
            (tmp / "assets").mkdir()
            outputs.append("assets/")
            for assets in asset_sets:
                for name, contents in assets.items():
                    (tmp / "assets" / name).write_bytes(contents)
        for name, text in files.items():
            (tmp / name).write_text(text)
        if stages:
            from footforge.usd import write_stage
            for stem, usd_stage in stages.items():
                outputs += write_stage(usd_stage, tmp, stem)
        report["outputs"] = outputs + ["build_report.json"]
        (tmp / "build_report.json").write_text(json.dumps(report, indent=2, default=json_default) + "\n")


def json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(type(value))


def versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version
    out = {}
    for pkg in ("footforge", "mujoco", "dm-control", "pin", "coacd", "trimesh", "xacro", "usd-core"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = "not installed"
    return out
