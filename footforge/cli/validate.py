"""`footforge validate`: drop tests of each variant beside the closed chain, and the fidelity report."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from footforge.cli.command import add_output_folder, new_parser
from footforge.cli.foot_options import add_description_options, description_options
from footforge.errors import EXIT_CHECK_FAILED, EXIT_OK

if TYPE_CHECKING:
    from footforge.validate.results import ValidationReport


def parser(prog: str = "footforge validate") -> argparse.ArgumentParser:
    """The options of `footforge validate`."""
    from footforge.validate.scenarios import QUICK, SCENARIOS  # names only: no build extra needed

    p = new_parser(
        prog,
        "Drop each variant's foot on its test rig onto the scenarios' grounds beside "
        "the 34-joint closed chain, and compare contact force, peak, final height, "
        "orientation, centre of pressure and slip against thresholds. Exit 1 when a "
        "variant fails a threshold.",
    )
    p.add_argument("--variant", default="all", help="aof, aff, ball, a comma-separated list, or all (default)")
    p.add_argument(
        "--scenarios",
        nargs="+",
        default=["quick"],
        metavar="NAME",
        help=f"quick (default: {', '.join(QUICK)}), all ({len(SCENARIOS)}: {', '.join(s.name for s in SCENARIOS)}),"
        " or scenario names",
    )
    p.add_argument(
        "--calibrate",
        action="store_true",
        help="fit the AFF/AOF springs, dampers and sole lift on a training subset and write them to the parameter file",
    )
    p.add_argument("--evaluations", type=int, default=120, help="objective evaluations per calibrated variant")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: all cores)")
    p.add_argument(
        "--threshold",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a fidelity threshold (force_nrmse, peak_force_rel, final_height_mm, "
        "orientation_deg, cop_mm, slip_mm); repeatable",
    )
    p.add_argument("--seed", type=int, default=0, help="offset for the random scenarios' seeds")
    add_description_options(
        p, params_help="variant parameter file (default: the SoftFoot-Q's; read, and written by --calibrate)"
    )
    add_output_folder(p, Path("validation"), "report folder (default validation/)")
    return p


def run(args: argparse.Namespace) -> int:
    """Runs the drop tests, writes the report; exit 1 where a variant fails a threshold."""
    from footforge.extras import require_build_extra

    require_build_extra("footforge validate")
    from footforge.cli.help import console as make_console, counted_progress
    from footforge.errors import InputError
    from footforge.models.foot_source import FootInputs
    from footforge.outputs import check_output_folder
    from footforge.validate import report as report_lib
    from footforge.validate.fidelity import Thresholds
    from footforge.validate.runner import ValidateOptions, parse_variants, validate
    from footforge.validate.scenarios import select

    console = make_console()

    if args.jobs < 1:
        raise InputError(f"--jobs {args.jobs} must be at least 1", fix="give a number of worker processes, e.g. 2")
    if args.evaluations < 2:
        raise InputError(f"--evaluations {args.evaluations} must be at least 2", fix="e.g. 120")
    select(args.scenarios)  # unknown names are usage errors before anything is built
    check_output_folder(args.out, force=args.force)  # before minutes of simulation
    options = ValidateOptions(
        variants=parse_variants(args.variant),
        scenarios=tuple(args.scenarios),
        calibrate=args.calibrate,
        calibration_evaluations=args.evaluations,
        jobs=args.jobs,
        thresholds=Thresholds.with_overrides(args.threshold),
        seed=args.seed,
        foot=FootInputs(**description_options(args)),
    )
    with counted_progress(console) as progress:

        def tracker(description: str, total: int):
            task = progress.add_task(description, total=total)
            return lambda: progress.advance(task)

        report = validate(options, progress=tracker)
        progress.add_task("writing the report", total=None)
        report_lib.write(report, args.out, "footforge " + " ".join(sys.argv[1:]), force=args.force)
    _print_validation(report, args.out, console)
    return EXIT_OK if report.passed else EXIT_CHECK_FAILED


def _print_validation(report: ValidationReport, out: Path, console) -> None:
    from rich.table import Table

    from footforge.validate.report import METRICS, failing_metrics, format_value

    ref = report.reference
    table = Table(title=f"footforge validate -> {out}/report.md")
    for column in ("variant", *METRICS, "speed vs full", "verdict"):
        table.add_column(column)
    for v, f in report.fidelity.items():
        m = f.summary.metrics
        table.add_row(
            v,
            *[format_value(m[k].mean) for k in METRICS],
            f"{report.speed[v].vs_full:.1f}x",
            "[green]pass[/green]" if f.summary.passed else "[red]FAIL[/red]",
        )
    table.add_row("threshold", *[format_value(report.thresholds[k]) for k in METRICS], "", "")
    console.print(table)
    for v, f in report.fidelity.items():
        failing = failing_metrics(f.summary)
        if failing:
            console.print(f"[red]{v} fails[/red] on: " + "; ".join(failing))
        if f.summary.missed_obstacle:
            console.print(f"{v} missed the obstacle in {', '.join(f.summary.missed_obstacle)}: excluded from the means")
    console.print(
        f"closed-chain reference: largest closure opening {format_value(ref.max_closure_gap_mm)} mm "
        f"(limit {ref.closure_limit_mm}), largest energy gain {format_value(ref.max_energy_gain_j)} J: "
        + ("[green]trustworthy[/green]" if ref.passed else "[red]NOT trustworthy[/red]")
    )
    for v, cal in (report.calibration or {}).items():
        console.print(
            f"calibrated {v}: objective {cal['series_errors_before']['train']['objective']:.3g} -> "
            f"{cal['series_errors_after']['train']['objective']:.3g} (train), "
            f"{format_value(cal['series_errors_before']['held_out'].get('objective'))} -> "
            f"{format_value(cal['series_errors_after']['held_out'].get('objective'))} (held out); "
            f"written to {cal['written_to']}"
        )
