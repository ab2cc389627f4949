"""The `footforge` command line: one command for every job, a thin layer over the library.

build, validate, check and export are parsed here; train, evaluate, evaluate-closed-chain and play
have their own modules beside this one (footforge/cli/), which pipelines/*.py also run.

Exit codes: 0 success, 1 check failures, 2 usage or input errors. Errors print as messages
that name the file, the element and the fix; `--verbose` adds the traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback
from pathlib import Path
from typing import TYPE_CHECKING

import footforge

footforge.headless_by_default()  # before any import of MuJoCo

from footforge.errors import (  # noqa: E402  (after headless_by_default)
    EXIT_CHECK_FAILED,
    EXIT_INPUT_ERROR,
    EXIT_OK,
    FootforgeError,
    interrupt_exit_code,
    interrupt_word,
)
from footforge.models.mesh_simplify import DEFAULT_FACE_BUDGET  # noqa: E402

if TYPE_CHECKING:
    from footforge.validate.results import ValidationReport


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        from footforge.cli.help import DefaultsHelpFormatter

        kwargs.setdefault("formatter_class", DefaultsHelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message):  # argparse's usage errors exit 2, as ours do
        self.print_usage(sys.stderr)
        self.exit(EXIT_INPUT_ERROR, f"footforge: error: {message}\n")


def _versions() -> str:
    """footforge's version and the simulators it was run with (what a bug report needs)."""
    from importlib.metadata import PackageNotFoundError, version

    import footforge

    parts = [footforge.__version__]
    for dist in ("mujoco", "mujoco-mjx", "jax", "brax"):
        try:
            parts.append(f"{dist} {version(dist)}")
        except PackageNotFoundError:
            parts.append(f"{dist} absent")
    return parts[0] + " (" + ", ".join(parts[1:]) + ")"


def _add_description_options(p: argparse.ArgumentParser, params_help: str | None = None) -> None:
    """The foot description and its derivation, the same for build and validate (a foot that builds
    with some flags validates with the same flags)."""
    p.add_argument("--description", type=Path, help="foot xacro/URDF (default: the project's SoftFoot-Q)")
    p.add_argument("--sidecar", type=Path, help="foot sidecar YAML (default: <stem>.sidecar.yaml beside it)")
    p.add_argument("--params", type=Path, help=params_help or "variant parameter file (default: the SoftFoot-Q's)")
    p.add_argument(
        "--package-path",
        type=Path,
        action="append",
        default=[],
        metavar="DIR",
        help="folder searched for ROS packages ($(find pkg), package://); repeatable",
    )
    p.add_argument(
        "--arg",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="xacro argument for the foot description; repeatable",
    )
    p.add_argument(
        "--repair", action="store_true", help="repair repairable description defects (reported in build_report.json)"
    )
    # DecompositionConfig's defaults (footforge.models.collision, whose trimesh import would slow every
    # command's start), checked against it by tests/test_cli.py.
    p.add_argument("--max-hull-vertices", type=int, default=64, help="vertex cap per convex hull (default %(default)s)")
    p.add_argument(
        "--coacd-timeout",
        type=float,
        default=900.0,
        help="seconds before CoACD is stopped, per mesh: a guard against a decomposition that never ends "
        "(it takes minutes on a busy machine)",
    )
    p.add_argument(
        "--face-budget",
        type=int,
        default=DEFAULT_FACE_BUDGET,
        help="simplify collision meshes above this many faces before CoACD (default %(default)s; 0: never)",
    )
    p.add_argument("--cache-dir", type=Path, help="CoACD cache folder (default ~/.cache/footforge/coacd)")


def _description_options(args) -> dict:
    """FootInputs fields (also BuildOptions's) from _add_description_options' flags, checked before any work.

    Raises:
      InputError: a hull vertex cap below 4, a non-positive CoACD timeout, a negative face budget.
    """
    from footforge.errors import InputError
    from footforge.inputs.description import parse_args
    from footforge.models.collision import DecompositionConfig

    if args.max_hull_vertices < 4:
        raise InputError(
            f"--max-hull-vertices {args.max_hull_vertices} is below 4",
            fix="a convex hull needs at least 4 vertices; the default is 64",
        )
    if args.coacd_timeout <= 0:
        raise InputError("--coacd-timeout must be positive", fix="give seconds, e.g. 900")
    if args.face_budget < 0:
        raise InputError(
            f"--face-budget {args.face_budget} is negative",
            fix=f"give a face count (default {DEFAULT_FACE_BUDGET}), or 0 to keep every face",
        )

    return dict(
        foot_description=args.description,
        sidecar=args.sidecar,
        params=args.params,
        package_paths=tuple(args.package_path),
        foot_args=parse_args(args.arg),
        repair=args.repair,
        cache_dir=args.cache_dir,
        decomposition=DecompositionConfig(
            max_hull_vertices=args.max_hull_vertices, timeout_s=args.coacd_timeout, face_budget=args.face_budget
        ),
    )


def _train(argv: list[str]) -> int:
    from footforge.cli.train import DESCRIPTIONS, main
    from footforge.envs import TASKS

    if not argv or argv[0] not in TASKS:
        usage = f"usage: footforge train {{{','.join(TASKS)}}} [options]   (footforge train flat --help lists them)"
        if argv and argv[0] in ("-h", "--help"):
            print(
                usage + "\n\nTrain a policy with Brax PPO on MuJoCo MJX: flat is the paper's flat-ground task, "
                "rough its terrain curriculum."
            )
            return EXIT_OK
        print(usage, file=sys.stderr)
        print(
            f"footforge train: error: the first argument is the task, one of {', '.join(TASKS)}"
            + (f" (got '{argv[0]}')" if argv else ""),
            file=sys.stderr,
        )
        return EXIT_INPUT_ERROR
    task = argv[0]
    return main(task, DESCRIPTIONS[task], argv[1:], prog=f"footforge train {task}")


def _delegate(module: str):
    def run(argv: list[str]) -> int:
        import importlib

        return importlib.import_module(f"footforge.cli.{module}").main(argv)

    return run


DELEGATED = {
    "train": (_train, "train a policy: footforge train flat|rough [options] (Brax PPO on MJX)"),
    "evaluate": (
        _delegate("evaluate"),
        "the paper's indices and the walking verdict of trained policies, on any feet; policy card, plots, GIF",
    ),
    "evaluate-closed-chain": (
        _delegate("evaluate_closed_chain"),
        "run trained policies on the 34-joint closed-chain feet (CPU MuJoCo)",
    ),
    "play": (
        _delegate("play"),
        "watch a trained policy walk: MuJoCo's viewer with keyboard commands, or headless with a GIF",
    ),
}
"""Subcommands with their own argument parsers: footforge <name> ARGS runs run(ARGS)."""

BUILD_EXTRA_COMMANDS = ("build", "validate", "check")
"""The jobs that read descriptions and build models: they need the build extra (footforge.extras)."""


def parsers() -> dict[str, argparse.ArgumentParser]:
    """Every job's argument parser by its command words ("build", ..., "train flat", "train rough"):
    what the help of each shows."""
    import importlib

    from footforge.cli import train
    from footforge.envs import TASKS

    top = _parser()
    jobs = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction)).choices
    found = {name: p for name, p in jobs.items() if name not in DELEGATED}
    for name in DELEGATED:
        if name == "train":
            found |= {
                f"train {task}": train.parser(task, train.DESCRIPTIONS[task], f"footforge train {task}")
                for task in TASKS
            }
        else:
            found[name] = importlib.import_module(f"footforge.cli.{name.replace('-', '_')}").parser()
    return found


def _parser() -> argparse.ArgumentParser:
    from footforge.validate.scenarios import QUICK, SCENARIOS  # names only: no build extra needed
    from footforge.variants import VARIANTS

    p = _Parser(prog="footforge", description=__doc__.splitlines()[0])
    p.add_argument("--verbose", action="store_true", help="print tracebacks on errors")
    p.add_argument("--version", action="version", version=f"footforge {_versions()}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    b = sub.add_parser(
        "build",
        help="build MJCF models of ANYmal C with a foot variant",
        description="Build ANYmal C with a foot variant: MuJoCo MJCF (robot.xml, scene.xml with "
        "keyframes home and stand, foot_rig.xml) and USD for Isaac Sim, from the "
        "SoftFoot-Q description or yours; mass properties checked against the closed "
        "chain with Pinocchio; collision hulls by CoACD (cached). About a minute on 2 cores.",
    )
    b.add_argument(
        "--variant",
        required=True,
        choices=VARIANTS,
        help="full: 34-joint closed chain; aof: split sole, 4 passive DOF; aff: flat sole, "
        "2 passive DOF; ball: ANYmal C's standard foot",
    )
    b.add_argument("--foot-only", action="store_true", help="write the foot alone (foot.xml) and its rig")
    _add_description_options(b)
    b.add_argument("--robot", type=Path, help="robot xacro/URDF with a foot:=ball|none argument (default: ANYmal C)")
    b.add_argument(
        "--format",
        default="mjcf,usd",
        metavar="FORMATS",
        help="comma-separated outputs: mjcf (MuJoCo XML), usd (robot.usda/.usd for Isaac Sim); default mjcf,usd",
    )
    b.add_argument(
        "--out",
        type=Path,
        help="output folder (default build/<variant>); replaced only if footforge "
        "wrote it (or it is empty), see --force",
    )
    b.add_argument(
        "--force", action="store_true", help="replace --out even if footforge did not write it (it may hold your files)"
    )

    v = sub.add_parser(
        "validate",
        help="drop tests of AFF/AOF/ball against the closed chain; fidelity report",
        description="Drop each variant's foot on its test rig onto the scenarios' grounds beside "
        "the 34-joint closed chain, and compare contact force, peak, final height, "
        "orientation, centre of pressure and slip against thresholds. Exit 1 when a "
        "variant fails a threshold.",
    )
    v.add_argument("--variant", default="all", help="aof, aff, ball, a comma-separated list, or all (default)")
    v.add_argument(
        "--scenarios",
        nargs="+",
        default=["quick"],
        metavar="NAME",
        help=f"quick (default: {', '.join(QUICK)}), all ({len(SCENARIOS)}: {', '.join(s.name for s in SCENARIOS)}),"
        " or scenario names",
    )
    v.add_argument(
        "--calibrate",
        action="store_true",
        help="fit the AFF/AOF springs, dampers and sole lift on a training subset and write them to the parameter file",
    )
    v.add_argument("--evaluations", type=int, default=120, help="objective evaluations per calibrated variant")
    v.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: all cores)")
    v.add_argument(
        "--threshold",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a fidelity threshold (force_nrmse, peak_force_rel, final_height_mm, "
        "orientation_deg, cop_mm, slip_mm); repeatable",
    )
    v.add_argument("--seed", type=int, default=0, help="offset for the random scenarios' seeds")
    _add_description_options(
        v, params_help="variant parameter file (default: the SoftFoot-Q's; read, and written by --calibrate)"
    )
    v.add_argument(
        "--out",
        type=Path,
        default=Path("validation"),
        help="report folder (default validation/); replaced only if footforge wrote it, see --force",
    )
    v.add_argument(
        "--force", action="store_true", help="replace --out even if footforge did not write it (it may hold your files)"
    )

    c = sub.add_parser(
        "check",
        help="report physical and structural defects of a URDF or xacro",
        description="Lint a URDF or xacro (inertias, masses, joints, meshes, and with --sidecar "
        "the closed chain's closures). Exit 1 when it finds an error.",
    )
    c.add_argument("path", type=Path, help="the URDF or xacro file")
    c.add_argument(
        "--package-path",
        type=Path,
        action="append",
        default=[],
        metavar="DIR",
        help="folder searched for ROS packages ($(find pkg), package://); repeatable",
    )
    c.add_argument("--arg", action="append", default=[], metavar="NAME:=VALUE", help="xacro argument; repeatable")
    c.add_argument("--sidecar", type=Path, help="also check that the sidecar's closures close")

    for name, (_, help_text) in DELEGATED.items():  # listed here, parsed by their own modules
        sub.add_parser(name, help=help_text, add_help=False)

    e = sub.add_parser(
        "export",
        help="write a trained policy as ONNX (normaliser inside, metadata for deployment)",
        description="Write a trained policy as one ONNX file: observation normaliser and network "
        "inside, the observation layout, action scale and joint order as metadata.",
    )
    e.add_argument(
        "policy_dir",
        type=Path,
        metavar="POLICY_DIR",
        help="a training run's folder (its policy/, or without one its newest intact checkpoint), its "
        "policy/ folder, or one of its checkpoints/<step>/ folders",
    )
    e.add_argument(
        "--out",
        type=Path,
        metavar="FILE.onnx",
        help="output file (default: RUN.onnx in the current "
        "folder, named after the run; RUN_stepN.onnx for a checkpoint); an existing file is replaced only "
        "where footforge exported it",
    )
    e.add_argument("--force", action="store_true", help="replace --out even if footforge did not write it")
    return p


def _run_build(args, console) -> int:
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from footforge.build import BuildOptions, build

    options = BuildOptions(
        variant=args.variant,
        out_dir=args.out or Path("build") / args.variant,
        foot_only=args.foot_only,
        robot_description=args.robot,
        force=args.force,
        formats=tuple(f.strip() for f in args.format.split(",") if f.strip()),
        **_description_options(args),
    )
    with Progress(
        SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), console=console, transient=True
    ) as progress:
        task = progress.add_task("building", total=None)
        report = build(options, progress=lambda stage: progress.update(task, description=stage))
    _print_summary(report, options.out_dir, console)
    return EXIT_OK


def _print_summary(report: dict, out_dir: Path, console) -> None:
    from rich.table import Table

    m = report["model"]
    table = Table(title=f"footforge build --variant {report['variant']} -> {out_dir}", show_header=False)
    table.add_row("bodies", str(m["bodies"]))
    table.add_row("joints", ", ".join(f"{v} {k}" for k, v in m["joints_by_kind"].items()))
    table.add_row("DOF", str(m["dof"]))
    table.add_row("equality constraints", ", ".join(f"{v} {k}" for k, v in m["equality_constraints"].items()) or "none")
    table.add_row("total mass", f"{m['total_mass_kg']:.5f} kg")
    table.add_row("timestep", f"{m['timestep_s'] * 1e3:g} ms")
    if "home_base_height_m" in m:
        table.add_row("home base height", f"{m['home_base_height_m']:.4f} m")
    if "closure_residual_at_home_m" in report:
        table.add_row("closure residual (home)", f"{report['closure_residual_at_home_m']:.2e} m")
    mp = report.get("mass_properties_vs_full")
    if mp:
        worst_inertia = max(f["centroidal_inertia_relative_error"] for f in mp["feet"].values())
        table.add_row(
            "vs full: mass, COM, foot inertia",
            f"{mp['total_mass']['relative_error']:.1e}, {mp['com']['relative_error']:.1e}, "
            f"{worst_inertia:.1e} (tol {mp['total_mass']['tolerance']:g}) "
            + ("[green]pass[/green]" if mp["passed"] else "[red]FAIL[/red]"),
        )
    for mesh in report.get("collision", {}).get("meshes", []):
        table.add_row(
            f"hulls {Path(mesh['mesh']).name}",
            f"{mesh['hulls']} (max {max(mesh['vertices'])} vertices{', cached' if mesh['cached'] else ''})",
        )
    for stem, u in report.get("usd", {}).items():
        c = u["vs_mjcf"]
        table.add_row(
            f"USD {stem}",
            f"valid; vs MJCF: mass {c['mass_rel']:.1e}, anchors {c['anchor_m']:.1e} m, "
            f"axes {c['axis_rad']:.1e} rad; {len(u['unsupported'])} item(s) not carried "
            "(build_report.json: usd.unsupported)",
        )
    for note in report.get("repairs", []):
        table.add_row("[yellow]repaired[/yellow]", note)
    table.add_row("time", f"{sum(report['timings_s'].values()):.2f} s")
    console.print(table)


def _run_validate(args, console) -> int:
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from footforge.errors import InputError
    from footforge.models.foot_source import FootInputs
    from footforge.outputs import check_output_folder
    from footforge.validate import report as report_lib
    from footforge.validate.fidelity import Thresholds
    from footforge.validate.runner import ValidateOptions, parse_variants, validate
    from footforge.validate.scenarios import select

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
        foot=FootInputs(**_description_options(args)),
    )
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
    ) as progress:

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


def _run_check(args, console) -> int:
    from footforge.build.check import check_description
    from footforge.inputs.description import parse_args
    from footforge.inputs.urdf_lint import format_findings

    result = check_description(
        args.path, package_paths=args.package_path, args=parse_args(args.arg), sidecar=args.sidecar
    )
    console.print(format_findings(result.findings), markup=False, highlight=False)
    for name, gap in result.closure_gaps_m.items():
        console.print(f"closure '{name}': gap {gap:.2e} m at the reference pose", markup=False)
    errors = sum(f.severity == "error" for f in result.findings)
    warnings = len(result.findings) - errors
    console.print(f"{args.path}: {errors} error(s), {warnings} warning(s)", markup=False)
    return EXIT_CHECK_FAILED if result.failed else EXIT_OK


def _run_export(args, console) -> int:
    from footforge.cli.guard import policy_in_use
    from footforge.rl.export_onnx import export

    out = export(policy_in_use(args.policy_dir, "footforge export"), args.out, force=args.force)
    console.print(f"policy written to {out}", markup=False, highlight=False, soft_wrap=True)
    return EXIT_OK


def _prog(argv: list[str]) -> str:
    """`footforge JOB` (with train's task) as the command's errors name it, or `footforge`."""
    words = [a for a in argv if not a.startswith("-")][:2]
    if not words or words[0] not in ("build", "validate", "check", "export", *DELEGATED):
        return "footforge"
    return (
        f"footforge {words[0]} {words[1]}"
        if words[0] == "train" and words[1:] in (["flat"], ["rough"])
        else f"footforge {words[0]}"
    )


def main(argv: list[str] | None = None) -> int:
    from footforge.processes import sigterm_as_interrupt

    with sigterm_as_interrupt():  # a terminated run cleans up as an interrupted one
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if footforge.gl_setting_refused(_prog(argv)):  # before `import mujoco` raises on it
        return EXIT_INPUT_ERROR
    first = next((i for i, a in enumerate(argv) if not a.startswith("-")), None)
    if first is not None and argv[first] in DELEGATED and all(a == "--verbose" for a in argv[:first]):
        try:
            return DELEGATED[argv[first]][0](argv[first + 1 :])
        except SystemExit as e:  # their argparse's --help (0) and usage errors (2), as exit codes
            return int(e.code or 0)
    try:
        args = _parser().parse_args(argv)
    except SystemExit as e:  # usage errors (2) and --help (0), as exit codes
        return int(e.code or 0)
    from footforge.cli.help import console

    console_out, errors = console(), console(stderr=True)
    try:
        run = {"build": _run_build, "validate": _run_validate, "check": _run_check, "export": _run_export}[args.command]
        if args.command in BUILD_EXTRA_COMMANDS:
            from footforge.extras import require_build_extra

            require_build_extra(f"footforge {args.command}")
        return run(args, console_out)
    except FootforgeError as e:
        if args.verbose:
            traceback.print_exc()
        errors.print(
            f"footforge {args.command}: error: {e}", markup=False, highlight=False, soft_wrap=True
        )  # paths unbroken
        return e.exit_code
    except KeyboardInterrupt as e:
        errors.print(f"footforge {args.command}: {interrupt_word(e)}; no output was written")
        return interrupt_exit_code(e)


if __name__ == "__main__":
    sys.exit(main())
