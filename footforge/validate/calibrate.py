"""Fit the AFF/AOF passive-joint springs and dampers and the sole lift to the closed chain.

Objective, on the training scenarios: the mean of (force RMS / force range)^2 + (height RMS /
5 mm)^2 + (sole orientation RMS / 5 deg)^2, all from time series so it varies smoothly with the
parameters. Free parameters: log10 stiffness and log10 damping of the ankle pitch, the ankle roll
and (AOF) the two sole hinges as one symmetric pair, plus the sole lift (params.sole_lift_m).
Nelder-Mead, deterministic; the fitted values are written into the parameter file, and the
variant is rebuilt from that file before its final runs, so what is reported is what
`footforge build` will make.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from footforge.errors import InputError
from footforge.inputs.params import VariantParams, load_params
from footforge.validate import fidelity
from footforge.variants import foot_variant

GROUPS = {
    "aff": (("ankle_pitch",), ("ankle_roll",)),
    "aof": (("ankle_pitch",), ("ankle_roll",), ("sole_front", "sole_back")),
}
LOG_STIFFNESS = (-3.0, 2.3)
"""log10 bounds, N m/rad (1e-3 .. 200)."""
LOG_DAMPING = (-4.0, 1.3)
"""log10 bounds, N m s/rad (1e-4 .. 20)."""
LIFT_CM = (0.0, 3.0)
"""Sole lift bounds, cm (the optimiser works in cm to keep the simplex balanced); the upper bound
is lowered to keep the sole 1 mm below the foot's other collision boxes (foot.sole_clearance), where they
collide (params.FootContact.upper_collisions)."""


def _vector(params, variant: str) -> np.ndarray:
    joints = params.joints_for(variant)
    x = []
    for group in GROUPS[variant]:
        j = joints[group[0]]
        x += [
            math.log10(min(max(j.stiffness, 10 ** LOG_STIFFNESS[0]), 10 ** LOG_STIFFNESS[1])),
            math.log10(min(max(j.damping, 10 ** LOG_DAMPING[0]), 10 ** LOG_DAMPING[1])),
        ]
    return np.array(x + [params.sole_lift_m[variant] * 100.0])


def _values(x: np.ndarray, variant: str) -> tuple[dict, float]:
    joints = {}
    for i, group in enumerate(GROUPS[variant]):
        for name in group:
            joints[name] = {"stiffness": float(f"{10 ** x[2 * i]:.4g}"), "damping": float(f"{10 ** x[2 * i + 1]:.4g}")}
    return joints, float(f"{x[-1] / 100.0:.4g}")


def training_split(scenarios: list) -> tuple[list, list]:
    """Calibration scenarios and held-out ones: every third scenario (in the listed order) is
    held out, so each obstacle family has members on both sides."""
    held = [s for i, s in enumerate(scenarios) if i % 3 == 2]
    return [s for s in scenarios if s not in held], held


def variant_params_summary(models, variant: str) -> dict:
    params = models.source.params
    joints = params.joints_for(variant)
    return {
        "joints": {n: {"stiffness": j.stiffness, "damping": j.damping} for n, j in joints.items()},
        "sole_lift_m": params.sole_lift_m[variant],
    }


def mean_series_errors(runs: dict[str, dict], full_runs: dict[str, dict], names) -> dict:
    """Each time-series error and the calibration objective, averaged over `names`."""
    errs = [fidelity.series_errors(runs[n], full_runs[n]) for n in names]
    if not errs:
        return {}
    return {k: float(np.mean([e[k] for e in errs])) for k in errs[0]} | {
        "objective": float(np.mean([fidelity.objective(e) for e in errs]))
    }


def calibrate(models, pool, scenarios, runs, options, advance) -> dict:
    train, held = training_split(scenarios)
    if not train:
        raise InputError("calibration needs scenarios to train on", fix="run --calibrate with --scenarios quick or all")
    out = {}
    for variant in [v for v in options.variants if foot_variant(v).derived]:
        params = models.source.params
        before = variant_params_summary(models, variant)
        cases = models.cases(variant, train)
        full = runs["full"]
        tick = advance(f"calibrating {variant}", options.calibration_evaluations)
        best, history = _fit(pool, cases, full, params, variant, models.feet[variant], options, tick)
        joints, lift = _values(best, variant)
        models.reload(variant, write_params(params.source, variant, joints, lift))
        new_runs = {
            r["scenario"]: r
            for r in pool.map(models.cases(variant, scenarios), advance(f"re-running {variant}", len(scenarios)))
        }
        out[variant] = {
            "parameters_before": before,
            "parameters_after": variant_params_summary(models, variant),
            "objective_before": history[0],
            "objective_after": float(min(history)),
            "evaluations": len(history),
            "objective_history": history,
            "written_to": str(params.source),
            "train": [s.name for s in train],
            "held_out": [s.name for s in held],
            "series_errors_before": {
                "train": mean_series_errors(runs[variant], full, [s.name for s in train]),
                "held_out": mean_series_errors(runs[variant], full, [s.name for s in held]),
            },
            "series_errors_after": {
                "train": mean_series_errors(new_runs, full, [s.name for s in train]),
                "held_out": mean_series_errors(new_runs, full, [s.name for s in held]),
            },
            "runs": new_runs,
        }
    return out


def _fit(pool, cases, full: dict, params, variant: str, foot, options, tick) -> tuple[np.ndarray, list[float]]:
    """Nelder-Mead over the variant's free parameters; returns the best point and the objective
    of every evaluation (the first is the starting point)."""
    history: list[float] = []

    def objective(x):
        joints, lift = _values(x, variant)
        patch = {"joints": joints, "sole_lift_delta_m": lift - params.sole_lift_m[variant]}
        results = pool.map([replace(c, patch=patch) for c in cases])
        value = float(
            np.mean(
                [
                    fidelity.objective(fidelity.series_errors(r, full[r["scenario"]])) if not r["failed"] else 1e6
                    for r in results
                ]
            )
        )
        history.append(value)
        tick()
        return value

    x0 = _vector(params, variant)
    clearance = foot.info["sole_clearance_m"]  # None when only the sole collides (params.FootContact)
    max_lift_cm = np.inf if clearance is None else 100.0 * (params.sole_lift_m[variant] + clearance - 0.0011)
    bounds = [LOG_STIFFNESS, LOG_DAMPING] * len(GROUPS[variant]) + [
        (LIFT_CM[0], max(LIFT_CM[0], min(LIFT_CM[1], max_lift_cm)))
    ]
    lower, upper = [b[0] for b in bounds], [b[1] for b in bounds]
    simplex = np.array([x0] + [np.clip(x0 + 0.5 * e, lower, upper) for e in np.eye(len(x0))])
    for i in range(1, len(simplex)):  # a step that hit a bound goes the other way
        if np.allclose(simplex[i], x0):
            simplex[i] = x0 - 0.5 * np.eye(len(x0))[i - 1]
    result = minimize(
        objective,
        x0,
        method="Nelder-Mead",
        bounds=bounds,
        options={"maxfev": options.calibration_evaluations, "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-5},
    )
    return (result.x if result.fun <= history[0] else x0), history


def write_params(path: Path, variant: str, joints: dict[str, dict], lift_m: float) -> VariantParams:
    """Rewrites the `variant` section's joint stiffness/damping and sole_lift_m in place,
    keeping every comment, other value and the file's permissions; checked by reading the
    written text back before it replaces the file.

    Returns:
      The parameters as now written.

    Raises:
      InputError: the file lacks the section or one of the joints.
    """
    path = Path(path)
    lines = path.read_text().splitlines(keepends=True)
    section, seen, lift_done = False, set(), False
    for i, line in enumerate(lines):
        header = re.match(r"^([A-Za-z_]\w*):", line)
        if header:
            section = header.group(1) == variant
            continue
        if not section:
            continue
        m = re.match(r"^(\s+)(\w+):\s*\{(.*)\}(.*)$", line.rstrip("\n"))
        if m and m.group(2) in joints:
            fields = dict(kv.split(":", 1) for kv in m.group(3).split(","))
            fields = {k.strip(): v.strip() for k, v in fields.items()}
            fields["stiffness"] = repr(joints[m.group(2)]["stiffness"])
            fields["damping"] = repr(joints[m.group(2)]["damping"])
            body = ", ".join(f"{k}: {v}" for k, v in fields.items())
            lines[i] = f"{m.group(1)}{m.group(2)}: {{{body}}}{m.group(4)}\n"
            seen.add(m.group(2))
        lift = re.match(r"^(\s+)sole_lift_m:\s*[-+0-9.eE]+(.*)$", line.rstrip("\n"))
        if lift:
            lines[i] = f"{lift.group(1)}sole_lift_m: {lift_m!r}{lift.group(2)}\n"
            lift_done = True
    missing = sorted(set(joints) - seen) + ([] if lift_done else ["sole_lift_m"])
    if missing:
        raise InputError(
            f"the parameter file has no {variant}.{', '.join(missing)} to update",
            file=str(path),
            element=variant,
            fix="start from the project's variant_params.yaml",
        )
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write("".join(lines))
        shutil.copymode(path, tmp)
        written = load_params(tmp)
        values = written.joints_for(variant)
        if not (
            all(
                math.isclose(values[n].stiffness, v["stiffness"]) and math.isclose(values[n].damping, v["damping"])
                for n, v in joints.items()
            )
            and math.isclose(written.sole_lift_m[variant], lift_m)
        ):
            raise InputError(
                "the rewritten parameter file does not read back as written",
                file=str(path),
                element=variant,
                fix="check the section's layout: one joint per line, flow mappings",
            )
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return replace(written, source=path.resolve())
