"""The validation report: report.md, report.html (same content), report.json (every figure),
series.npz (the time series) and plots/*.png, written atomically into one folder."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np

from footforge.atomic import atomic_directory
from footforge.provenance import json_default
from footforge.tables import markdown_table
from footforge.validate import fidelity as fidelity_lib
from footforge.validate.results import FidelitySummary, ValidationReport
from footforge.variants import VARIANTS, foot_variant

METRICS = ("force_nrmse", "peak_force_rel", "final_height_mm", "orientation_deg", "cop_mm", "slip_mm")
COLOURS: dict[str, str] = {v: foot_variant(v).colour for v in VARIANTS}
"""Each variant's colour in the report's plots (footforge.variants)."""


def format_value(value, digits=3) -> str:
    """A report figure as text: n/a for a missing or non-finite one, pass/FAIL for a verdict."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    if isinstance(value, bool):
        return "pass" if value else "FAIL"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def failing_metrics(summary: FidelitySummary) -> list[str]:
    """'name mean > threshold' for each metric whose mean exceeds its threshold, and the runs
    that failed, in words a user can act on."""
    out = [
        f"{name} {format_value(m.mean)} > {format_value(m.threshold)}"
        for name, m in summary.metrics.items()
        if m.passed is False
    ]
    if summary.failed_runs:
        out.append("runs failed: " + ", ".join(summary.failed_runs))
    return out


def document_items(report: ValidationReport, command: str) -> list[tuple]:
    """The report as a document both report.md and report.html render: a list of ("h", level, text),
    ("p", text), ("table", header, rows) and ("img", path, alt) items."""
    out: list[tuple] = [
        ("h", 1, "footforge validate"),
        ("p", f"Command: `{command}`"),
        (
            "p",
            f"footforge {report.footforge}, mujoco {report.versions.get('mujoco')}, "
            f"machine {report.machine}, seed {report.seed}, {report.jobs} worker(s); "
            f"parameters {report.params}.",
        ),
        (
            "p",
            "Verdict: " + ("PASS" if report.passed else "FAIL") + ". A pass needs a trustworthy "
            "reference and every variant's mean errors within the thresholds.",
        ),
    ]
    ref = report.reference
    out += [
        ("h", 2, "The closed-chain reference"),
        (
            "p",
            f"Largest closure opening {format_value(ref.max_closure_gap_mm)} mm (limit {ref.closure_limit_mm} mm); "
            f"largest energy gain over the initial energy {format_value(ref.max_energy_gain_j)} J "
            f"(tolerance {ref.energy_gain_tolerance_j} J): {format_value(ref.passed)}.",
        ),
        (
            "table",
            ["scenario", "max closure gap (mm)", "energy gain (J)", "failure"],
            [
                [n, format_value(p["max_closure_gap_mm"]), format_value(p["energy_gain_j"]), p["failed"] or ""]
                for n, p in ref.per_scenario.items()
            ],
        ),
    ]
    out += [
        ("h", 2, "Fidelity summary (mean over scenarios, against the closed chain)"),
        (
            "table",
            ["variant", *METRICS, "speed vs full", "verdict"],
            [
                [
                    v,
                    *[
                        f"{format_value(f.summary.metrics[m].mean)} (max {format_value(f.summary.metrics[m].max)})"
                        for m in METRICS
                    ],
                    f"{report.speed[v].vs_full:.1f}x",
                    format_value(f.summary.passed),
                ]
                for v, f in report.fidelity.items()
            ],
        ),
        (
            "p",
            "Thresholds (mean): "
            + ", ".join(f"{k} {v:g}" for k, v in report.thresholds.items())
            + ". Speed: simulated seconds per wall-clock second over the same scenarios, "
            f"full = {report.speed['full'].realtime_factor:.2f}.",
        ),
    ]
    for v, f in report.fidelity.items():
        failing = failing_metrics(f.summary)
        if failing:
            out.append(("p", f"{v} fails on: " + "; ".join(failing) + "."))
        missed = f.summary.missed_obstacle
        if missed:
            out.append(
                (
                    "p",
                    f"{v}: the obstacle carried under {fidelity_lib.OBSTACLE_SHARE_MIN:.0%} of the ground "
                    f"impulse in {', '.join(missed)} (it landed beside it); excluded from the means.",
                )
            )
    if report.calibration is not None:
        out.append(("h", 2, "Calibration"))
        for v, cal in report.calibration.items():
            rows = []
            for key in ("force", "height_mm", "orientation_deg", "objective"):
                rows.append(
                    [key]
                    + [
                        format_value(cal[f"series_errors_{when}"][split].get(key))
                        for when in ("before", "after")
                        for split in ("train", "held_out")
                    ]
                )
            out += [
                ("h", 3, v),
                (
                    "p",
                    f"{cal['evaluations']} evaluations on {len(cal['train'])} training scenarios "
                    f"({', '.join(cal['train'])}); held out: {', '.join(cal['held_out']) or 'none'}. "
                    f"Written to {cal['written_to']}.",
                ),
                (
                    "table",
                    ["time-series error", "before (train)", "before (held out)", "after (train)", "after (held out)"],
                    rows,
                ),
                ("table", ["parameter", "before", "after"], _param_rows(cal)),
            ]
    out.append(("h", 2, "Per scenario"))
    for v, f in report.fidelity.items():
        out += [
            ("h", 3, v),
            (
                "table",
                ["scenario", *METRICS],
                [
                    [n, "run failed"]
                    if e.get("failed")
                    else [n, "obstacle missed (excluded)"]
                    if e.get("missed_obstacle")
                    else [n, *[format_value(e.get(m)) for m in METRICS]]
                    for n, e in f.per_scenario.items()
                ],
            ),
        ]
    out.append(("h", 2, "Scalars per run"))
    keys = (
        "peak_force_n",
        "impulse_ns",
        "settling_time_s",
        "final_height_m",
        "final_pitch_deg",
        "final_roll_deg",
        "contacts",
        "cop_x_mm",
        "cop_y_mm",
        "spread_mm",
        "rebound_mm",
        "slip_mm",
        "max_penetration_mm",
    )
    for v, runs in report.runs.items():
        out += [
            ("h", 3, v),
            (
                "table",
                ["scenario", *keys],
                [[n, *[format_value(r["scalars"].get(k)) for k in keys]] for n, r in runs.items()],
            ),
        ]
    out.append(("h", 2, "Plots"))
    for s in report.scenarios:
        out.append(("img", f"plots/{s['name']}.png", s["name"]))
    return out


def _param_rows(cal: dict) -> list[list[str]]:
    b, a = cal["parameters_before"], cal["parameters_after"]
    rows = [
        [f"{j}.{k}", format_value(b["joints"][j][k], 4), format_value(a["joints"][j][k], 4)]
        for j in b["joints"]
        for k in ("stiffness", "damping")
    ]
    return rows + [["sole_lift_m", format_value(b["sole_lift_m"], 4), format_value(a["sole_lift_m"], 4)]]


def to_markdown(items: list[tuple]) -> str:
    lines = []
    for item in items:
        if item[0] == "h":
            lines += ["#" * item[1] + " " + item[2], ""]
        elif item[0] == "p":
            lines += [item[1], ""]
        elif item[0] == "table":
            lines += markdown_table(item[1], item[2]) + [""]
        elif item[0] == "img":
            lines += [f"![{item[2]}]({item[1]})", ""]
    return "\n".join(lines)


def _html_text(text: str) -> str:
    """Escaped text with markdown's `code` spans as <code> (the markdown report's own markup)."""
    parts = html.escape(text).split("`")
    return "".join(f"<code>{p}</code>" if i % 2 else p for i, p in enumerate(parts))


def _html_cell(text: str) -> str:
    css = {"pass": "pass", "FAIL": "fail"}.get(text.strip(), "")
    return f"<td class='{css}'>{_html_text(text)}</td>" if css else f"<td>{_html_text(text)}</td>"


def to_html(items: list[tuple]) -> str:
    e = html.escape
    body = []
    for item in items:
        if item[0] == "h":
            body.append(f"<h{item[1]}>{e(item[2])}</h{item[1]}>")
        elif item[0] == "p":
            body.append(f"<p>{_html_text(item[1])}</p>")
        elif item[0] == "table":
            head = "".join(f"<th>{e(h)}</th>" for h in item[1])
            rows = "".join("<tr>" + "".join(_html_cell(c) for c in row) + "</tr>" for row in item[2])
            body.append(f"<div class='scroll'><table><tr>{head}</tr>{rows}</table></div>")
        elif item[0] == "img":
            body.append(
                f'<figure><img src="{e(item[1])}" alt="{e(item[2])}" width="900"><figcaption>{e(item[2])}'
                "</figcaption></figure>"
            )
    style = (
        "body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
        "font-size:12px;margin:8px 0}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}"
        ".scroll{overflow-x:auto;max-width:100%}td.pass{background:#d8f5d8}td.fail{background:#f8d0d0;"
        "font-weight:bold}img{max-width:100%;height:auto}code{background:#f2f2f2}"
    )
    return (
        f"<!doctype html><html><head><meta charset='utf-8'><title>footforge validate</title><style>{style}</style>"
        f"</head><body>{''.join(body)}</body></html>\n"
    )


def plot_scenario(report: ValidationReport, scenario: str, path: Path) -> None:
    """Vertical force of each variant over the reference, sole pitch and roll, final footprint."""
    from matplotlib.figure import Figure  # no pyplot: a library leaves the backend to its user

    fig = Figure(figsize=(15, 4))
    axes = fig.subplots(1, 3)
    # The main force axis shows the settling (up to 4x the weight); the inset shows the whole
    # range, impact peaks included, on a log scale.
    peaks = axes[0].inset_axes([0.5, 0.5, 0.47, 0.45])
    for v, runs in report.runs.items():
        r = runs[scenario]
        s, c = r["series"], COLOURS.get(v, None)
        width = 2.0 if foot_variant(v).closed_chain else 1.0  # the reference, drawn heavier
        axes[0].plot(s["time_s"], s["force_z_n"], color=c, lw=width, label=v)
        peaks.plot(s["time_s"], np.maximum(s["force_peak_n"], 1.0), color=c, lw=0.8)
        if np.isfinite(s["pitch_rad"]).any():
            axes[1].plot(s["time_s"], np.degrees(s["pitch_rad"]), color=c, lw=width, label=f"{v} pitch")
            axes[1].plot(s["time_s"], np.degrees(s["roll_rad"]), color=c, lw=width, ls="--", label=f"{v} roll")
        fp = r["footprint"]
        if len(fp):
            axes[2].scatter(
                fp[:, 0] * 1e3,
                fp[:, 1] * 1e3,
                s=10 + 60 * np.clip(fp[:, 2], 0, None) / max(fp[:, 2].max(), 1e-9),
                color=c,
                alpha=0.6,
                label=v,
            )
    axes[0].set(
        xlabel="time (s)",
        ylabel="vertical ground force (N)",
        title=f"{scenario}: force",
        ylim=(0, 4 * max(r[scenario]["supported_weight_n"] for r in report.runs.values())),
    )
    peaks.set_yscale("log")
    peaks.set_title("peak force per interval (N, log)", fontsize=7)
    peaks.tick_params(labelsize=6)
    axes[1].set(xlabel="time (s)", ylabel="deg", title="sole pitch (solid) and roll (dashed)")
    axes[2].set(xlabel="x (mm)", ylabel="y (mm)", title="settled contacts (size ~ force)", aspect="equal")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=80)


def write(report: ValidationReport, out_dir: Path, command: str, *, force: bool = False) -> None:
    """Writes the report folder as a whole; `force` replaces a folder footforge did not write."""
    with atomic_directory(out_dir, force=force, command=command) as tmp:
        (tmp / "plots").mkdir()
        for s in report.scenarios:
            plot_scenario(report, s["name"], tmp / "plots" / f"{s['name']}.png")
        items = document_items(report, command)
        (tmp / "report.md").write_text(to_markdown(items))
        (tmp / "report.html").write_text(to_html(items))
        (tmp / "report.json").write_text(json.dumps(report.to_json(), indent=1, default=json_default) + "\n")
        np.savez_compressed(
            tmp / "series.npz",
            **{
                f"{v}/{n}/{k}": a
                for v, runs in report.runs.items()
                for n, r in runs.items()
                for k, a in r["series"].items()
            },
        )
