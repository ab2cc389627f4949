"""`footforge check`: a description's defects, with values and fixes; sidecar closures too."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from footforge.errors import CheckFailure
from footforge.inputs.description import load_description
from footforge.inputs.foot_root import select_foot_root
from footforge.inputs.sidecar import load_sidecar
from footforge.inputs.urdf_lint import Finding, check_urdf, has_errors
from footforge.models import kinematics
from footforge.models.urdf import parse_urdf


@dataclass(frozen=True)
class CheckResult:
    findings: list[Finding]
    closure_gaps_m: dict[str, float]
    """Per closure, the gap at the sidecar's reference pose (empty without a sidecar)."""

    @property
    def failed(self) -> bool:
        return has_errors(self.findings)


def check_description(
    path: str | Path,
    *,
    package_paths: Sequence[str | Path] = (),
    args: Mapping[str, str] | None = None,
    sidecar: str | Path | None = None,
) -> CheckResult:
    """Checks a URDF or xacro file (and, given a sidecar, that its closures close).

    Raises:
      InputError: the file cannot be read or expanded.
    """
    description = load_description(path, args=args, package_paths=package_paths)
    findings = check_urdf(description.root(), resolve_uri=description.resolve_uri)
    gaps: dict[str, float] = {}
    if sidecar is not None and not has_errors(findings):
        side = load_sidecar(sidecar)
        foot, _ = select_foot_root(description, side.root_link, sidecar_path=side.source)
        parsed = parse_urdf(foot, floating=True)
        try:
            q = kinematics.reference_pose(parsed, side).q
        except CheckFailure as e:
            # The loops could not be closed: report each gap with the chain pins at zero and the
            # listed joints at their reference angles, then the failure.
            q = kinematics.pin.neutral(parsed.model)
            for name, value in side.reference_joints.items():
                kinematics.set_joint(parsed, q, name, value)
            findings.append(Finding("error", "closure_open", e.element or "sidecar", e.message, e.fix or "", False))
        residuals = kinematics.closure_residuals(parsed, side, q)
        gaps = {c.name: float(np.linalg.norm(r)) for c, r in zip(side.closures, residuals)}
        findings += [
            Finding("error", "closure_axis", element, message, fix, False)
            for element, message, fix in kinematics.closure_axis_problems(parsed, side, q)
        ]
    return CheckResult(findings, gaps)
