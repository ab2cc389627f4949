"""Fidelity of a variant: its difference from the closed chain on the same scenario, and the
thresholds that decide pass or fail."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np

from footforge.errors import InputError


@dataclass(frozen=True)
class Thresholds:
    """Largest accepted mean (over the scenarios run) of each fidelity error."""

    force_nrmse: float = 0.15
    """RMS difference of the vertical ground force curves over the full chain's force range."""
    peak_force_rel: float = 0.5
    """|peak - peak_full| / peak_full (impacts are stiff: peaks are sensitive to the contact model)."""
    final_height_mm: float = 5.0
    """Difference of the loaded foot mount's height after settling, mm."""
    orientation_deg: float = 5.0
    """Difference of the settled sole's pitch and roll (Euclidean), deg."""
    cop_mm: float = 10.0
    """Difference of the settled centre of pressure, mm."""
    slip_mm: float = 5.0
    """Difference of the sole's horizontal sliding, from the moment the weight is carried to rest, mm."""

    @classmethod
    def with_overrides(cls, items: list[str] | None) -> Thresholds:
        """Defaults overridden by NAME=VALUE strings.

        Raises:
          InputError: unknown name or a value that is not a positive number.
        """
        t = cls()
        names = {f.name for f in fields(cls)}
        for item in items or []:
            name, _, value = item.partition("=")
            if name not in names:
                raise InputError(f"unknown threshold '{name}'", fix=f"use one of {', '.join(sorted(names))}")
            try:
                number = float(value)
            except ValueError:
                number = float("nan")
            if not math.isfinite(number) or number <= 0:
                raise InputError(f"threshold {name}={value!r} is not a positive number", fix=f"e.g. {name}=0.2")
            t = replace(t, **{name: number})
        return t

    def as_dict(self) -> dict:
        return asdict(self)


OBSTACLE_SHARE_MIN = 0.01
"""An obstacle scenario engaged a foot only if the obstacle carried at least this share of the
ground impulse over the run; below it the foot missed the obstacle (the ball, a point under the
middle of the sole, misses a step under the toe) and the run says nothing about obstacles."""


def missed_obstacle(run: dict) -> bool:
    return run["scalars"].get("obstacle_share", 1.0) < OBSTACLE_SHARE_MIN


def errors(variant: dict, full: dict) -> dict:
    """Fidelity errors of one variant run against the full chain's run of the same scenario."""
    if variant["scalars"].get("failed") or full["scalars"].get("failed"):
        return {"failed": True}
    if missed_obstacle(variant) or missed_obstacle(full):
        return {"failed": False, "missed_obstacle": True}
    a, b = variant["scalars"], full["scalars"]
    orientation = math.hypot(a["final_pitch_deg"] - b["final_pitch_deg"], a["final_roll_deg"] - b["final_roll_deg"])
    return {
        "force_nrmse": series_errors(variant, full)["force"],
        "peak_force_rel": abs(a["peak_force_n"] - b["peak_force_n"]) / b["peak_force_n"],
        "final_height_mm": abs(a["final_height_m"] - b["final_height_m"]) * 1e3,
        "orientation_deg": orientation,  # NaN for the ball foot: it has no sole
        "cop_mm": math.hypot(a["cop_x_mm"] - b["cop_x_mm"], a["cop_y_mm"] - b["cop_y_mm"]),
        "slip_mm": abs(a["slip_mm"] - b["slip_mm"]),
        "failed": False,
    }


def _common_samples(sv: dict, sf: dict) -> int:
    """Number of samples both runs share; they must be on the same time grid."""
    n = min(len(sv["time_s"]), len(sf["time_s"]))
    if not np.allclose(sv["time_s"][:n], sf["time_s"][:n], atol=1e-9):
        raise ValueError("runs sampled at different instants cannot be compared")
    return n


def series_errors(variant: dict, full: dict) -> dict:
    """Time-series errors, smooth in the parameters (the calibration's objective terms): force
    RMS over the force range, and from the reference's first contact on (before it both fall
    alike, only offset by where their soles sit) height RMS (mm) and sole pitch/roll RMS (deg)."""
    sv, sf = variant["series"], full["series"]
    n = _common_samples(sv, sf)
    touched = np.flatnonzero(sf["force_z_n"][:n] > 1e-6)
    after = slice(int(touched[0]) if touched.size else 0, n)
    ff = sf["force_z_n"][:n]
    span = max(float(np.nanmax(ff) - np.nanmin(ff)), 1e-9)

    def rms(x):
        x = x[np.isfinite(x)]
        return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")

    return {
        "force": rms(sv["force_z_n"][:n] - ff) / span,
        "height_mm": rms(sv["height_m"][after] - sf["height_m"][after]) * 1e3,
        "orientation_deg": float(
            np.degrees(
                np.hypot(
                    rms(sv["pitch_rad"][after] - sf["pitch_rad"][after]),
                    rms(sv["roll_rad"][after] - sf["roll_rad"][after]),
                )
            )
        ),
    }


HEIGHT_SCALE_MM = 5.0
ORIENTATION_SCALE_DEG = 5.0


def objective(errors: dict) -> float:
    """The calibration objective of one scenario: (force error)^2 + (height error / 5 mm)^2 +
    (orientation error / 5 deg)^2 (the last left out where the variant has no sole)."""
    orientation = errors["orientation_deg"]
    return (
        errors["force"] ** 2
        + (errors["height_mm"] / HEIGHT_SCALE_MM) ** 2
        + (0.0 if math.isnan(orientation) else (orientation / ORIENTATION_SCALE_DEG) ** 2)
    )


def summarise(per_scenario: dict[str, dict], thresholds: Thresholds) -> dict:
    """Mean and worst of each error over the scenarios, and pass/fail against the thresholds
    (a metric that is undefined for the variant, like the ball's sole orientation, is skipped, and
    so are scenarios whose obstacle the variant or the closed chain missed: `missed_obstacle`)."""
    out: dict[str, Any] = {
        "metrics": {},
        "passed": True,
        "failed_runs": sorted(s for s, e in per_scenario.items() if e.get("failed")),
        "missed_obstacle": sorted(s for s, e in per_scenario.items() if e.get("missed_obstacle")),
    }
    for name, limit in thresholds.as_dict().items():
        values = np.array(
            [e[name] for e in per_scenario.values() if not e.get("failed") and not e.get("missed_obstacle")], float
        )
        values = values[np.isfinite(values)]
        if not values.size:
            out["metrics"][name] = {"mean": None, "max": None, "threshold": limit, "passed": None}
            continue
        mean = float(values.mean())
        passed = mean <= limit
        out["metrics"][name] = {"mean": mean, "max": float(values.max()), "threshold": limit, "passed": passed}
        out["passed"] &= passed
    if out["failed_runs"]:
        out["passed"] = False
    return out
