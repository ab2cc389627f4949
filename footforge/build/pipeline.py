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

import json
import platform
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import mujoco

from footforge import constants as C
from footforge.atomic import atomic_directory
from footforge.build.report import closure_gaps, model_counts
from footforge.errors import CheckFailure, InputError
from footforge.inputs.description import default_robot_description, load_description
from footforge.inputs.params import load_params
from footforge.inputs.urdf_lint import link_inertia_checks, lint_and_repair
from footforge.mjcf import foot as foot_lib
from footforge.mjcf.rig import build_rig
from footforge.mjcf.robot import build_robot
from footforge.mjcf.scene import scene_xml
from footforge.mjcf.writing import compile_model, xml_with_assets
from footforge.models import massprops
from footforge.models.foot_source import FootInputs, load_foot_source
from footforge.models.massprops import MASS_RTOL, compare_mass_properties
from footforge.models.urdf import parse_urdf
from footforge.outputs import check_output_folder
from footforge.provenance import json_default, sha256_file, versions
from footforge.timing import StageTimer
from footforge.variants import VARIANTS, Variant, foot_variant  # noqa: F401  (VARIANTS, Variant re-exported: footforge.build)

FORMATS = ("mjcf", "usd")

REPORT_FORMAT = C.BUILD_FORMAT


@dataclass(frozen=True, kw_only=True)
class BuildOptions(FootInputs):
    """What to build and where; where the foot comes from is FootInputs' fields."""

    variant: Variant
    """Which feet: full (closed chain), aof, aff, ball."""
    out_dir: Path
    """Output folder; replaced as a whole when the build succeeds (if new, empty, or written by
    footforge: footforge.outputs)."""
    force: bool = False
    """Replace `out_dir` even if footforge did not write it (the user's --force)."""
    foot_only: bool = False
    """Write the foot alone (foot.xml) and its rig, no robot."""
    robot_description: Path | None = None
    """Robot xacro/URDF with a `foot` argument (ball|none); default ANYmal C. `repair` applies to
    it too."""
    formats: tuple[str, ...] = FORMATS
    """Which outputs: "mjcf" (MuJoCo XML and assets) and/or "usd" (for Isaac Sim)."""


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
        raise InputError(
            f"unknown output format '{', '.join(unknown)}'" if unknown else "no output format given",
            fix=f"use one or more of {', '.join(FORMATS)}, e.g. --format mjcf,usd",
        )
    check_output_folder(options.out_dir, force=options.force)  # before minutes of CoACD
    stage = StageTimer(progress)
    report: dict = {
        "format": REPORT_FORMAT,
        "variant": options.variant,
        "foot_only": options.foot_only,
        "versions": versions(),
        "machine": platform.platform(),
        "repairs": [],
        "warnings": [],
    }
    params = load_params(options.params)
    report["inputs"] = {"params": {"path": str(params.source), "sha256": sha256_file(params.source)}}
    files: dict[str, str] = {}
    asset_sets: list[dict] = []
    stages: dict[str, object] = {}
    if "usd" in options.formats:
        report["usd"] = {}

    foot = full_foot = None
    sidecar = None
    kind = foot_variant(options.variant)
    if kind.adaptive:  # the SoftFoot-Q description builds it
        source = load_foot_source(options, stage, report, params)
        sidecar = source.sidecar
        with stage(f"build {options.variant} foot"):
            full_foot = foot_lib.build_full(source)
            foot = full_foot if kind.closed_chain else foot_lib.build_derived(source, options.variant, full=full_foot)
            report["foot"] = foot.info | {
                "passive_joints": foot.passive_joints,
                "reference_qpos_rad": foot.reference_qpos,
                "touchdown_m": foot.touchdown.tolist(),
            }

    friction = sidecar.friction if sidecar else 0.8
    with stage("build rig"):
        rig = build_rig(foot, C.BALL_FOOT_RADIUS_M, variant=options.variant, params=params, friction=friction)
        files["foot_rig.xml"] = xml_with_assets(rig.mjcf, asset_sets)
        rig_model = compile_model(rig.mjcf)
        report["foot_rig"] = model_counts(rig_model) | {"payload_kg": params.rig_payload_mass}
    _export_usd(options, stage, report, stages, "foot_rig", rig_model, "reference")

    if options.foot_only:
        if foot is None:
            raise InputError("--foot-only needs an adaptive foot variant", fix="use --variant full, aof or aff")
        with stage("write foot model"):
            files["foot.xml"] = xml_with_assets(foot.mjcf, asset_sets)
            foot_model = compile_model(foot.mjcf)
            report["model"] = model_counts(foot_model)
        _export_usd(options, stage, report, stages, "foot", foot_model, None)
    else:
        with stage("build robot"):
            robot_path = Path(options.robot_description or default_robot_description())
            foot_arg = "none" if kind.adaptive else "ball"  # the robot description's own ball foot
            robot_desc = load_description(robot_path, args={"foot": foot_arg}, package_paths=options.package_paths)
            robot_desc, robot_findings, notes = lint_and_repair(robot_desc, repair=options.repair, what="robot")
            report["repairs"] += [f"{robot_path.name}: {n}" for n in notes]
            report["inputs"]["robot_description"] = {
                "path": str(robot_desc.source),
                "sha256": sha256_file(robot_desc.source),
                "args": {"foot": foot_arg},
            }
            report.setdefault("link_inertia_checks", {})["robot"] = link_inertia_checks(robot_desc, robot_findings)
            robot_parsed = parse_urdf(robot_desc, floating=True)
            robot = build_robot(robot_parsed, foot, variant=options.variant, params=params, friction=friction)
            files["robot.xml"] = xml_with_assets(robot.mjcf, asset_sets)
            files["scene.xml"] = scene_xml("robot.xml", options.variant)
            robot_model = compile_model(robot.mjcf)
            report["model"] = model_counts(robot_model)
            report["model"]["home_base_height_m"] = float(robot_model.key("home").qpos[2])
        _export_usd(options, stage, report, stages, "robot", robot_model, "home")
        if kind.closed_chain:
            with stage("check closures"):
                data = massprops.at_keyframe(robot_model, "home")
                gaps = closure_gaps(robot_model, data)
                report["closure_residual_at_home_m"] = max(gaps.values())
        elif kind.derived:
            with stage("compare mass properties"):
                full_robot = build_robot(
                    robot_parsed, full_foot, variant="full", params=params, friction=friction, stand_keyframe=False
                )
                full_model = compile_model(full_robot.mjcf)
                roots = [f"{C.FOOT_MODEL_NAME.format(leg=leg)}/{foot.root_body}" for leg in C.LEGS]  # type: ignore[union-attr]
                comparison = compare_mass_properties(robot_model, full_model, "home", roots)
                report["mass_properties_vs_full"] = comparison
    report["timings_s"] = stage.timings_s
    if "mass_properties_vs_full" in report and not report["mass_properties_vs_full"]["passed"]:
        raise CheckFailure(
            "mass properties of the derived feet differ from the closed chain's beyond "
            f"{MASS_RTOL:g}: {json.dumps(report['mass_properties_vs_full'])}",
            fix="report this as a bug: derived bodies must be exact composites",
        )
    if "mjcf" not in options.formats:
        files, asset_sets = {}, []
    _write_atomically(options.out_dir, files, asset_sets, report, stages, force=options.force)
    return report


def _export_usd(
    options: BuildOptions,
    stage: StageTimer,
    report: dict,
    stages: dict,
    stem: str,
    model: mujoco.MjModel,
    keyframe: str | None,
) -> None:
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
    report["usd"][stem] = {
        "files": list(usd.stage_files(stem)),
        "keyframe": keyframe,
        "validation": findings,
        "vs_mjcf": comparison,
        "tolerances": usd.TOLERANCES,
        **exported.report(),
    }
    if errors:
        raise CheckFailure(
            f"the exported {stem} USD stage fails usd-core's validation:\n"
            + "\n".join(f"  {e['name']}: {e['message']} ({', '.join(e['prims'])})" for e in errors),
            fix="report this as a bug in footforge's USD exporter; use --format mjcf meanwhile",
        )
    failures = usd.comparison_failures(comparison)
    if failures:
        raise CheckFailure(
            f"the exported {stem} USD stage differs from its MJCF model:\n  " + "\n  ".join(failures),
            fix="report this as a bug in footforge's USD exporter; use --format mjcf meanwhile",
        )
    stages[stem] = exported.stage


def _write_atomically(
    out_dir: Path,
    files: dict[str, str],
    asset_sets: list[dict],
    report: dict,
    stages: Mapping[str, object] = {},
    *,
    force: bool = False,
) -> None:
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
