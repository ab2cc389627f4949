"""Everything a foot variant is derived from: the checked foot description and sidecar, the
closed chain's reference pose, and the collision meshes' convex hulls."""

from __future__ import annotations

import difflib
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from footforge.errors import CheckFailure, InputError
from footforge.inputs.description import default_foot_description, load_description
from footforge.inputs.foot_root import select_foot_root
from footforge.inputs.params import VariantParams, load_params
from footforge.inputs.sidecar import Sidecar, find_sidecar, load_sidecar
from footforge.inputs.urdf_lint import link_inertia_checks, lint_and_repair
from footforge.models import kinematics
from footforge.models.collision import DecompositionConfig, Hulls, decompose
from footforge.models.urdf import ParsedURDF, is_mesh, parse_urdf
from footforge.provenance import sha256_file
from footforge.timing import StageTimer


@dataclass(frozen=True)
class FootInputs:
    """Where a foot comes from: the files and settings `load_foot_source` reads."""

    foot_description: Path | None = None
    """Foot xacro/URDF; default descriptions/softfoot_q/urdf/softfoot_q.urdf.xacro."""
    sidecar: Path | None = None
    """Foot sidecar; default <stem>.sidecar.yaml beside the foot description."""
    package_paths: tuple[Path, ...] = ()
    """Folders searched for ROS packages before ROS_PACKAGE_PATH and the project's own."""
    foot_args: Mapping[str, str] = field(default_factory=dict)
    """xacro arguments for the foot description."""
    params: Path | None = None
    """Variant parameter file; default descriptions/softfoot_q/config/variant_params.yaml."""
    repair: bool = False
    """Repair the description's repairable defects (reported) instead of refusing them."""
    decomposition: DecompositionConfig = DecompositionConfig()
    """CoACD's settings for the collision meshes."""
    cache_dir: Path | None = None
    """CoACD cache; default ~/.cache/footforge/coacd (or $FOOTFORGE_CACHE)."""


@dataclass
class FootSource:
    """Everything a variant is derived from."""

    parsed: ParsedURDF
    sidecar: Sidecar
    params: VariantParams
    reference: kinematics.ReferencePose
    hulls: dict[str, Hulls]
    """Pinocchio collision geometry name -> its convex hulls (meshes only)."""

    @property
    def families(self) -> dict[int, str]:
        return kinematics.joint_families(self.parsed, self.sidecar)


def decompose_collision_meshes(
    parsed: ParsedURDF, config: DecompositionConfig, *, cache_dir=None, progress=None, starting=None
) -> dict[str, Hulls]:
    """Hulls of every collision mesh of `parsed`, decomposing each distinct file once.

    `starting(mesh_path, number, count)` is called before each distinct mesh (CoACD can take a
    minute on one: the user sees which), `progress(mesh_path, hulls)` after it."""
    by_file: dict[str, Hulls] = {}
    out = {}
    meshes = [go for go in parsed.collision.geometryObjects if is_mesh(go)]
    distinct = list(dict.fromkeys(f"{go.meshPath}|{tuple(go.meshScale)}" for go in meshes))
    for go in meshes:
        key = f"{go.meshPath}|{tuple(go.meshScale)}"
        if key not in by_file:
            if starting:
                starting(go.meshPath, distinct.index(key) + 1, len(distinct))
            hulls = decompose(go.meshPath, config, cache_dir=cache_dir)
            if not np.allclose(go.meshScale, 1.0):
                hulls = Hulls(
                    tuple(v * np.asarray(go.meshScale) for v in hulls.vertices),
                    hulls.faces,
                    hulls.decomposed,
                    hulls.cached,
                )
            by_file[key] = hulls
            if progress:
                progress(go.meshPath, hulls)
        out[go.name] = by_file[key]
    return out


def load_foot_source(
    options: FootInputs, stage: StageTimer, report: dict, params: VariantParams | None = None
) -> FootSource:
    """Reads and checks the foot description and its sidecar, solves the reference pose and
    decomposes the collision meshes: everything every foot variant is built from.

    `params` are the already loaded options.params, if the caller has them. Provenance (paths and
    digests of the inputs), repairs, warnings and the meshes' decomposition go into `report`.

    Raises:
      InputError: bad input (missing files, malformed descriptions, names the sidecar gets wrong).
      CheckFailure: the description has errors that --repair does not or may not fix.
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
        description, findings, notes = lint_and_repair(description, repair=options.repair, what="foot")
        report.setdefault("repairs", []).extend(f"{path.name}: {n}" for n in notes)
        report.setdefault("warnings", []).extend(f"{path.name}: {f.element}: {f.message}" for f in findings)
        inputs = report.setdefault("inputs", {})
        inputs["foot_description"] = {
            "path": str(description.source),
            "sha256": sha256_file(description.source),
            "args": dict(options.foot_args),
        }
        inputs["sidecar"] = {"path": str(sidecar.source), "sha256": sha256_file(sidecar.source)}
        report["link_inertia_checks"] = {"foot": link_inertia_checks(description, findings)}
        parsed = parse_urdf(description, floating=True)
        check_sidecar_names(parsed, sidecar)
    with stage("solve reference pose"):
        reference = kinematics.reference_pose(parsed, sidecar)
        problems = kinematics.closure_axis_problems(parsed, sidecar, reference.q)
        if problems:
            element, message, fix = problems[0]
            raise CheckFailure(
                f"{element}: {message}" + (f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""),
                file=str(sidecar.source),
                element=element,
                fix=fix,
            )
    with stage("decompose collision meshes"):
        hull_report = []
        started_s = [0.0]

        def starting(mesh, i, n):
            started_s[0] = time.perf_counter()
            stage.progress(f"decompose collision meshes: {i}/{n} {Path(mesh).name}")

        hulls = decompose_collision_meshes(
            parsed,
            options.decomposition,
            cache_dir=options.cache_dir,
            starting=starting,
            progress=lambda mesh, h: hull_report.append(
                {
                    "mesh": str(mesh),
                    "hulls": len(h.vertices),
                    "vertices": [len(v) for v in h.vertices],
                    "decomposed": h.decomposed,
                    "cached": h.cached,
                    "seconds": round(time.perf_counter() - started_s[0], 3),
                }
            ),
        )
        report["collision"] = {"config": asdict(options.decomposition), "meshes": hull_report}
    return FootSource(parsed, sidecar, params, reference, hulls)


def check_sidecar_names(parsed, sidecar: Sidecar) -> None:
    """Every joint and link the sidecar names must be in the description: a typo is the sidecar's,
    so the message names the sidecar file and the key to edit, and the closest names."""
    wanted: list[tuple[str, str, str]] = [(f"arch_joints[{i}]", "joint", n) for i, n in enumerate(sidecar.arch_joints)]
    wanted += [("roll_joints.front", "joint", sidecar.roll_front), ("roll_joints.back", "joint", sidecar.roll_back)]
    if sidecar.roll_coupling:
        wanted += [
            ("roll_coupling.joint", "joint", sidecar.roll_coupling.joint),
            ("roll_coupling.follows", "joint", sidecar.roll_coupling.follows),
        ]
    if sidecar.arch_spring:
        wanted += [("arch_spring.joints", "joint", n) for n in sidecar.arch_spring.joints]
    wanted += [("reference_pose.joints", "joint", n) for n in sidecar.reference_joints]
    for i, c in enumerate(sidecar.closures):
        wanted += [(f"closures[{i}].link", "link", c.link), (f"closures[{i}].to_link", "link", c.to_link)]
    root = parsed.description.root()
    names = {
        "joint": [j.get("name") for j in root.findall("joint")],
        "link": [e.get("name") for e in root.findall("link")],
    }
    unknown = [(key, kind, name) for key, kind, name in wanted if name not in names[kind]]
    if unknown:
        lines = []
        for key, kind, name in unknown:
            near = difflib.get_close_matches(name, names[kind], n=2, cutoff=0.5)
            lines.append(
                f"  {key}: {kind} '{name}' is not in the description"
                + (f" (closest: {', '.join(near)})" if near else "")
            )
        raise InputError(
            f"the sidecar names {len(unknown)} joint(s)/link(s) that {parsed.description.source.name} "
            "does not have:\n" + "\n".join(lines),
            file=str(sidecar.source),
            element=unknown[0][0],
            fix=f"edit those keys in {sidecar.source} to the description's names as expanded "
            "(with the macro's prefix, if any), or pass the right sidecar with --sidecar",
        )
