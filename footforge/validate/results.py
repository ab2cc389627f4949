"""What `footforge validate` finds, as typed objects: ValidationReport and its parts.

`report.json` is ValidationReport.to_json() (its layout unchanged since reports were plain
dicts, so reports written before still load: ValidationReport.from_json); JSON_SCHEMA_PATH holds
its JSON Schema, generated from these classes (json_schema) and checked against them by
tests/test_validate.py. Per-scenario figures stay mappings keyed by the names that
footforge.validate.fidelity and footforge.validate.simulate give them.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

JSON_SCHEMA_PATH = Path(__file__).with_name("report.schema.json")
"""The JSON Schema of report.json, shipped with the package."""


@dataclass(frozen=True)
class MetricSummary:
    """One error metric of a variant over the scenarios (footforge.validate.fidelity.summarise)."""

    mean: float | None
    """Mean over the scenarios that count; None where the metric is undefined for the variant."""
    max: float | None
    """Worst scenario."""
    threshold: float
    """The mean a pass allows (ValidateOptions.thresholds)."""
    passed: bool | None
    """mean <= threshold; None where undefined."""


@dataclass(frozen=True)
class FidelitySummary:
    """A variant's errors against the closed chain, summarised, and its verdict."""

    metrics: dict[str, MetricSummary]
    """Per metric (force_nrmse, peak_force_rel, final_height_mm, orientation_deg, cop_mm, slip_mm)."""
    passed: bool
    """Every defined metric within its threshold and no run failed."""
    failed_runs: list[str]
    """Scenarios whose simulation failed (a failure of the variant)."""
    missed_obstacle: list[str]
    """Scenarios whose obstacle the foot missed (left out of the means)."""


@dataclass(frozen=True)
class Fidelity:
    """A variant against the closed chain."""

    per_scenario: dict[str, dict[str, Any]]
    """Per scenario: each metric's error (footforge.validate.fidelity.errors)."""
    summary: FidelitySummary


@dataclass(frozen=True)
class Speed:
    """How fast a variant's drop tests ran."""

    simulated_s: float
    """Simulated seconds, summed over the scenarios."""
    wall_s: float
    """Wall-clock seconds, summed over the scenarios."""
    realtime_factor: float
    """simulated_s / wall_s."""
    vs_full: float
    """realtime_factor over the closed chain's."""


@dataclass(frozen=True)
class ReferenceChecks:
    """Whether the closed chain is trustworthy as the reference."""

    per_scenario: dict[str, dict[str, Any]]
    """Per scenario: failed (the reason, or false), max_closure_gap_mm, energy_gain_j."""
    max_closure_gap_mm: float
    """Largest opening of a loop closure over the scenarios, mm."""
    closure_limit_mm: float
    max_energy_gain_j: float
    """Largest gain of energy over the initial energy, J (a passive system must not gain any)."""
    energy_gain_tolerance_j: float
    passed: bool


@dataclass(frozen=True)
class ValidationReport:
    """Everything `footforge validate` measured, in report.json's order."""

    footforge: str
    """footforge's version."""
    versions: dict[str, str | None]
    """The tools' versions (mujoco, ...)."""
    machine: str
    seed: int
    jobs: int
    """Worker processes."""
    thresholds: dict[str, float]
    """The pass thresholds of the mean errors."""
    params: str
    """The variant parameter file."""
    inputs: dict[str, Any]
    """The descriptions read, with their SHA-256."""
    scenarios: list[dict[str, Any]]
    """Each scenario's description (footforge.validate.scenarios.Scenario.describe)."""
    sole_extent_m: dict[str, float]
    """The closed chain's sole: half_length_m, half_width_m."""
    reference: ReferenceChecks
    speed: dict[str, Speed]
    """Per variant, the closed chain ("full") included."""
    fidelity: dict[str, Fidelity]
    """Per derived variant or ball."""
    passed: bool
    """A trustworthy reference and every variant's verdict a pass."""
    runs: dict[str, dict[str, dict[str, Any]]] = field(default_factory=dict)
    """Per variant and scenario: the run's scalars and, until written, its series (which
    report.json leaves to series.npz)."""
    calibration: dict[str, dict[str, Any]] | None = None
    """Per calibrated variant (`--calibrate`): errors and parameters before and after."""

    def to_json(self) -> dict:
        """report.json's content: the series left out (series.npz holds them)."""
        out = {
            f.name: to_plain(getattr(self, f.name))
            for f in fields(self)
            if f.name not in ("runs", "calibration", "passed")
        }
        if self.calibration is not None:
            out["calibration"] = to_plain(self.calibration)
        out["passed"] = self.passed
        out["runs"] = {
            v: {n: {k: r[k] for k in RUN_KEYS if k in r} for n, r in runs.items()} for v, runs in self.runs.items()
        }
        return out

    @classmethod
    def from_json(cls, data: dict) -> ValidationReport:
        """A report from report.json (also those written before reports were typed; keys they
        lack, inputs and sole_extent_m, come back empty)."""
        return from_plain(cls, {"inputs": {}, "sole_extent_m": {}} | data)


RUN_KEYS = ("scalars", "failed", "wall_s", "steps", "timestep_s", "supported_weight_n", "hanging_mass_kg")
"""What report.json keeps of each run (the series go to series.npz)."""


def to_plain(value):
    """A typed report part (or anything holding one) as plain JSON values."""
    if dataclasses.is_dataclass(value):
        return {f.name: to_plain(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, dict):
        return {k: to_plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_plain(v) for v in value]
    return value


def from_plain(tp, value):
    """`value` (plain JSON values) as type `tp`: a dataclass of this module, a dict or list of
    them, or a plain type (returned as it is); the inverse of to_plain."""
    hints = typing.get_type_hints(tp) if dataclasses.is_dataclass(tp) else None
    if hints is not None:
        return tp(**{f.name: from_plain(hints[f.name], value[f.name]) for f in fields(tp) if f.name in value})
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is dict and value is not None:
        return {k: from_plain(args[1], v) for k, v in value.items()}
    if origin is list and value is not None:
        return [from_plain(args[0], v) for v in value]
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        return None if value is None else from_plain(inner[0], value)
    return value


def json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of report.json, from the classes above."""
    definitions: dict[str, dict | None] = {}

    def schema(tp) -> dict:
        if isinstance(tp, type) and dataclasses.is_dataclass(tp):  # a class, never an instance, here
            if tp.__name__ not in definitions:
                definitions[tp.__name__] = None  # reserved against recursion
                hints = typing.get_type_hints(tp)
                definitions[tp.__name__] = {
                    "type": "object",
                    "description": (tp.__doc__ or "").split("\n\n")[0].strip(),
                    "properties": {f.name: schema(hints[f.name]) for f in fields(tp)},
                    "required": [
                        f.name
                        for f in fields(tp)
                        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
                    ],
                }
            return {"$ref": f"#/$defs/{tp.__name__}"}
        origin, args = typing.get_origin(tp), typing.get_args(tp)
        if origin is dict:
            return {"type": "object", "additionalProperties": schema(args[1])}
        if origin is list:
            return {"type": "array", "items": schema(args[0])}
        if origin in (typing.Union, types.UnionType):
            return {"anyOf": [schema(a) for a in args]}
        return {
            str: {"type": "string"},
            int: {"type": "integer"},
            float: {"type": "number"},
            bool: {"type": "boolean"},
            type(None): {"type": "null"},
            Any: {},
        }[tp]

    root = schema(ValidationReport)
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "footforge validate: report.json",
        **root,
        "$defs": definitions,
    }
