"""`footforge validate`: drop every variant and the closed chain on the same scenarios, in
parallel processes, and measure how far the variants are from the reference."""

from __future__ import annotations

import multiprocessing
import os
import platform
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field, replace

from footforge import __version__
from footforge.errors import InputError
from footforge.inputs.params import VariantParams
from footforge.mjcf import foot as foot_lib
from footforge.models.foot_source import FootInputs, load_foot_source
from footforge.processes import die_with_parent
from footforge.provenance import versions
from footforge.timing import StageTimer
from footforge.validate import calibrate as calibration, fidelity, rigs, simulate
from footforge.validate.results import (
    Fidelity,
    FidelitySummary,
    ReferenceChecks,
    Speed,
    ValidationReport,
    from_plain,
    to_plain,
)
from footforge.validate.scenarios import Scenario, select
from footforge.variants import VALIDATED

CLOSURE_LIMIT_MM = 0.5
"""The closed chain is a trustworthy reference only if no loop opens by more than this."""
ENERGY_GAIN_TOL_J = 1e-3
"""Released at rest with only gravity, springs and dissipation acting, the rig's energy must not
exceed its initial value by more than this (about 1e-4 of a 10 cm drop's energy)."""


@dataclass(frozen=True)
class ValidateOptions:
    variants: tuple[str, ...] = VALIDATED
    """Variants compared with the closed chain."""
    scenarios: tuple[str, ...] = ("quick",)
    """'quick', 'all' or scenario names."""
    calibrate: bool = False
    """Fit the AFF/AOF spring, damper and sole-lift parameters and write them to the parameter file."""
    calibration_evaluations: int = 120
    """Objective evaluations per calibrated variant (each runs the training scenarios)."""
    jobs: int = 2
    """Worker processes."""
    thresholds: fidelity.Thresholds = field(default_factory=fidelity.Thresholds)
    seed: int = 0
    """Added to every random scenario's seed (rough patches)."""
    foot: FootInputs = FootInputs()
    """Foot description, sidecar, parameter file, packages and CoACD cache to build from."""


def parse_variants(text: str) -> tuple[str, ...]:
    if text == "all":
        return VALIDATED
    names = tuple(v.strip() for v in text.split(",") if v.strip())
    bad = [v for v in names if v not in VALIDATED]
    if bad or not names:
        raise InputError(f"unknown variant '{', '.join(bad)}' for validate", fix="use aof, aff, ball or all")
    return names


class Pool:
    """Worker processes that simulate rig cases; `map` keeps the input order.

    The workers exit when this process dies (processes.die_with_parent): killed, it would
    otherwise leave them blocked on their pipes forever. Interrupted, `close` drops the pending
    cases instead of running them."""

    def __init__(self, jobs: int):
        self.jobs = max(1, int(jobs))
        self._pool = (
            ProcessPoolExecutor(
                self.jobs,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=die_with_parent,
                initargs=(os.getpid(),),
            )
            if self.jobs > 1
            else None
        )

    def map(self, cases: list[simulate.RigCase], progress: Callable[[], None] | None = None) -> list[dict]:
        results = []
        iterator = map(simulate.run, cases) if self._pool is None else self._pool.map(simulate.run, cases)
        for result in iterator:
            results.append(result)
            if progress:
                progress()
        return results

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)


def _seeded(scenarios: list[Scenario], seed: int) -> list[Scenario]:
    return [replace(s, seed=s.seed + seed) if s.obstacle == "rough" else s for s in scenarios]


class ValidationModels:
    """The models of one validation: the foot source, each variant's foot, the sole extent."""

    def __init__(self, options: ValidateOptions, stage: StageTimer):
        self.inputs: dict = {}
        """Input files with their hashes, checks and warnings (build_report's form)."""
        self.source = load_foot_source(options.foot, stage, self.inputs)
        self.feet = rigs.build_feet(self.source, options.variants)
        self.sole = rigs.sole_extent(self.feet["full"])  # type: ignore[arg-type]  # the closed chain has a foot model

    def reload(self, variant: str, params: VariantParams) -> None:
        """Rebuilds `variant`'s foot with updated parameters."""
        self.source = replace(self.source, params=params)
        self.feet[variant] = foot_lib.build_derived(self.source, variant, full=self.feet["full"])

    def cases(self, variant: str, scenarios: list[Scenario]) -> list[simulate.RigCase]:
        return [
            rigs.rig_case(self.feet[variant], variant, s, self.sole, self.source.params, self.source.sidecar.friction)
            for s in scenarios
        ]


def reference_checks(runs: dict[str, dict]) -> ReferenceChecks:
    """The closed chain's own trustworthiness over the scenarios run."""
    per = {}
    for name, r in runs.items():
        sc = r["scalars"]
        per[name] = {
            "failed": r["failed"],
            "max_closure_gap_mm": sc.get("max_closure_gap_mm"),
            "energy_gain_j": sc.get("energy_gain_j"),
        }
    ok = [p for p in per.values() if not p["failed"]]
    worst_gap = max((p["max_closure_gap_mm"] for p in ok), default=float("nan"))
    worst_gain = max((p["energy_gain_j"] for p in ok), default=float("nan"))
    passed = len(ok) == len(per) and worst_gap <= CLOSURE_LIMIT_MM and worst_gain <= ENERGY_GAIN_TOL_J
    return ReferenceChecks(
        per_scenario=per,
        max_closure_gap_mm=worst_gap,
        closure_limit_mm=CLOSURE_LIMIT_MM,
        max_energy_gain_j=worst_gain,
        energy_gain_tolerance_j=ENERGY_GAIN_TOL_J,
        passed=passed,
    )


def speed(runs: dict[str, dict], full_realtime_factor: float | None = None) -> Speed:
    """Simulated seconds per wall-clock second, summed over the scenarios, and over the closed
    chain's (`full_realtime_factor`; None: these are the closed chain's runs)."""
    simulated = sum(r["steps"] * r["timestep_s"] for r in runs.values())
    wall = sum(r["wall_s"] for r in runs.values())
    factor = simulated / wall if wall else float("nan")
    return Speed(
        simulated_s=simulated,
        wall_s=wall,
        realtime_factor=factor,
        vs_full=factor / (factor if full_realtime_factor is None else full_realtime_factor),
    )


def compare(variant_runs: dict[str, dict], full_runs: dict[str, dict], thresholds: fidelity.Thresholds) -> Fidelity:
    """A variant's errors against the closed chain per scenario, and their summary."""
    per = {name: fidelity.errors(run, full_runs[name]) for name, run in variant_runs.items()}
    return Fidelity(per_scenario=per, summary=from_plain(FidelitySummary, fidelity.summarise(per, thresholds)))


def validate(
    options: ValidateOptions, *, progress: Callable[[str, int], Callable[[], None]] | None = None
) -> ValidationReport:
    """Runs the validation; returns the report (figures, series, definitions) without writing it.

    `progress(description, total)` returns a callback to advance by one finished run.
    """
    scenarios = _seeded(select(list(options.scenarios)), options.seed)
    stage = StageTimer(None)
    models = ValidationModels(options, stage)
    advance = progress or (lambda description, total: lambda: None)
    pool = Pool(options.jobs)
    try:
        variants = ("full",) + options.variants
        cases = [c for v in variants for c in models.cases(v, scenarios)]
        results = pool.map(cases, advance("drop tests", len(cases)))
        runs: dict[str, dict[str, dict]] = {v: {} for v in variants}
        for r in results:
            runs[r["variant"]][r["scenario"]] = r
        fidelity_of = {v: compare(runs[v], runs["full"], options.thresholds) for v in options.variants}
        calibrated = None
        if options.calibrate:
            calibrated = calibration.calibrate(models, pool, scenarios, runs, options, advance)
            for v, cal in calibrated.items():
                cal["fidelity_summary_before"] = to_plain(fidelity_of[v].summary)
                runs[v] = cal.pop("runs")
                fidelity_of[v] = compare(runs[v], runs["full"], options.thresholds)
    finally:
        pool.close()
    reference = reference_checks(runs["full"])
    full = speed(runs["full"])
    return ValidationReport(
        footforge=__version__,
        versions=versions(),
        machine=platform.platform(),
        seed=options.seed,
        jobs=options.jobs,
        thresholds=options.thresholds.as_dict(),
        params=str(models.source.params.source),
        inputs=models.inputs.get("inputs", {}),
        scenarios=[s.describe() for s in scenarios],
        sole_extent_m=asdict(models.sole),
        reference=reference,
        speed={v: speed(runs[v], full.realtime_factor) for v in variants},
        fidelity=fidelity_of,
        calibration=calibrated,
        runs=runs,
        passed=bool(reference.passed and all(f.summary.passed for f in fidelity_of.values())),
    )
