"""`footforge validate`: the closed-chain reference, drop-test physics, fidelity, calibration."""

import json
import shutil

import numpy as np
import pytest

from footforge.cli.main import main
from footforge.errors import InputError
from footforge.inputs.params import load_params
from footforge.validate import fidelity
from footforge.validate.calibrate import write_params
from footforge.validate.results import JSON_SCHEMA_PATH, ValidationReport, json_schema
from footforge.validate.runner import (
    CLOSURE_LIMIT_MM,
    ENERGY_GAIN_TOL_J,
    ValidateOptions,
    validate,
)
from footforge.validate.scenarios import QUICK, SCENARIOS, select

from conftest import REPO

PARAMS = REPO / "descriptions/softfoot_q/config/variant_params.yaml"


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """The quick set end to end through the command line, as CI runs it: (exit code, report.json
    read back as a ValidationReport, folder)."""
    out = tmp_path_factory.mktemp("validate") / "report"
    code = main(["validate", "--scenarios", "quick", "--jobs", "2", "--out", str(out)])
    return code, ValidationReport.from_json(json.loads((out / "report.json").read_text())), out


@pytest.fixture(scope="module")
def extra():
    """Scenarios outside the quick set that the physics checks need, full chain and AOF."""
    return validate(
        ValidateOptions(
            variants=("aof",), jobs=2, scenarios=("rock_middle", "leg_roll_+10deg", "leg_roll_-10deg", "rough_seed0")
        )
    )


def test_quick_run_writes_every_output(quick):
    code, report, out = quick
    # The ball has no sole to stand on: its settled height misses the closed chain's by about 4 cm,
    # far past the 5 mm threshold, so the quick set cannot pass and the exit code says so.
    assert report.fidelity["ball"].summary.passed is False and not report.passed and code == 1
    for name in ("report.md", "report.html", "report.json", "series.npz"):
        assert (out / name).is_file()
    assert sorted(p.stem for p in (out / "plots").iterdir()) == sorted(QUICK)
    assert [s["name"] for s in report.scenarios] == list(QUICK)
    assert set(report.fidelity) == {"aof", "aff", "ball"}
    assert report.versions["mujoco"] and report.seed == 0
    series = np.load(out / "series.npz")
    assert series["full/flat_2cm/force_z_n"].shape == series["aof/flat_2cm/force_z_n"].shape
    html = (out / "report.html").read_text()
    assert "<table>" in html and "plots/flat_2cm.png" in html


def test_closed_chain_reference_is_trustworthy(quick, extra):
    """Loops stay shut within 0.5 mm, nothing blows up, and the energy never exceeds its start."""
    _, report, _ = quick
    for ref in (report.reference, extra.reference):
        assert ref.passed
        assert ref.max_closure_gap_mm < CLOSURE_LIMIT_MM
        assert ref.max_energy_gain_j <= ENERGY_GAIN_TOL_J
        assert not any(p["failed"] for p in ref.per_scenario.values())


def test_settled_force_on_flat_ground_equals_the_supported_weight(quick):
    _, report, _ = quick
    for variant, runs in report.runs.items():
        run = runs["flat_2cm"]
        assert run["scalars"]["final_force_n"] == pytest.approx(run["supported_weight_n"], rel=0.01), variant


def test_symmetric_obstacle_gives_a_symmetric_response(extra):
    """A rock under the middle of the sole: no roll, no lateral centre of pressure; a leg tilted
    +10 or -10 degrees in roll: mirror images."""
    for variant, runs in extra.runs.items():
        rock = runs["rock_middle"]["scalars"]
        assert abs(rock["final_roll_deg"]) < 0.1 and abs(rock["cop_y_mm"]) < 0.5, variant
        plus, minus = runs["leg_roll_+10deg"]["scalars"], runs["leg_roll_-10deg"]["scalars"]
        # 0.1 deg: 2% of the orientation threshold. The closed chain's mirror runs differ by the
        # order in which its 20-odd contacts enter the solver (0.06 deg once its band stopped pushing).
        assert plus["final_roll_deg"] == pytest.approx(-minus["final_roll_deg"], abs=0.1), variant
        assert plus["cop_y_mm"] == pytest.approx(-minus["cop_y_mm"], abs=0.5), variant
        assert plus["final_height_m"] == pytest.approx(minus["final_height_m"], abs=1e-5), variant


def test_errors_measure_known_departures_from_the_reference(extra):
    """A copy of each closed-chain run moved by known amounts (force x1.1, 2 mm higher, pitch and
    roll +3 and +4 deg, centre of pressure +3 and +4 mm, 1.5 mm more slip) has exactly those
    errors: relative peak 0.1, height 2 mm, orientation and centre of pressure 5 (3-4-5), slip
    1.5 mm, force NRMSE 0.1 RMS(F) / span(F)."""
    import copy

    for name, run in extra.runs["full"].items():
        moved = copy.deepcopy(run)
        a, series = moved["scalars"], moved["series"]
        a["peak_force_n"] *= 1.1
        series["force_z_n"] = np.asarray(series["force_z_n"]) * 1.1
        a["final_height_m"] += 0.002
        a["final_pitch_deg"] += 3.0
        a["final_roll_deg"] += 4.0
        a["cop_x_mm"] += 3.0
        a["cop_y_mm"] += 4.0
        a["slip_mm"] += 1.5
        errors = fidelity.errors(moved, run)
        force = np.asarray(run["series"]["force_z_n"])
        n = min(len(force), len(series["force_z_n"]))
        expected_nrmse = (
            0.1
            * np.sqrt(np.mean(force[:n][np.isfinite(force[:n])] ** 2))
            / (np.nanmax(force[:n]) - np.nanmin(force[:n]))
        )
        assert errors["peak_force_rel"] == pytest.approx(0.1, rel=1e-9), name
        assert errors["final_height_mm"] == pytest.approx(2.0, rel=1e-6), name
        assert errors["orientation_deg"] == pytest.approx(5.0, rel=1e-9), name
        assert errors["cop_mm"] == pytest.approx(5.0, rel=1e-9), name
        assert errors["slip_mm"] == pytest.approx(1.5, rel=1e-9), name
        assert errors["force_nrmse"] == pytest.approx(expected_nrmse, rel=1e-9), name
        assert fidelity.errors(run, run)["force_nrmse"] == 0.0


def test_same_seed_same_figures_other_seed_other_terrain(extra):
    again = validate(ValidateOptions(variants=("aof",), jobs=1, scenarios=("rough_seed0",)))
    assert again.runs["aof"]["rough_seed0"]["scalars"] == extra.runs["aof"]["rough_seed0"]["scalars"]
    other = validate(ValidateOptions(variants=("aof",), jobs=1, scenarios=("rough_seed0",), seed=7))
    assert other.runs["aof"]["rough_seed0"]["scalars"] != extra.runs["aof"]["rough_seed0"]["scalars"]


def test_scenario_sets():
    assert len(SCENARIOS) >= 24 and 5 <= len(QUICK) <= 7
    assert {s.obstacle for s in SCENARIOS} == {"flat", "slope", "step", "cylinder", "rock", "rough"}
    assert {s.drop_height_m for s in SCENARIOS} >= {0.02, 0.05, 0.10}
    assert [s.name for s in select("all")] == [s.name for s in SCENARIOS]
    assert [s.name for s in select(["rock_front,flat_2cm"])] == ["rock_front", "flat_2cm"]
    with pytest.raises(InputError, match="unknown scenario"):
        select(["flat_2cm", "lava"])


@pytest.mark.parametrize(
    "argv,message",
    [
        (["--scenarios", "lava"], "unknown scenario(s): lava"),
        (["--threshold", "cop_mm=-1"], "not a positive number"),
        (["--threshold", "beauty=1"], "unknown threshold 'beauty'"),
        (["--variant", "hoof"], "unknown variant 'hoof'"),
        (["--jobs", "0"], "--jobs 0 must be at least 1"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(tmp_path, capsys, argv, message):
    assert main(["validate", *argv, "--out", str(tmp_path / "v")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "v").exists()


def test_write_params_keeps_comments_and_other_values(tmp_path):
    path = tmp_path / "params.yaml"
    shutil.copy(PARAMS, path)
    before = path.read_text()
    write_params(path, "aof", {"ankle_pitch": {"stiffness": 1.25, "damping": 0.5}}, 0.0123)
    after = path.read_text()
    params = load_params(path)
    assert params.aof["ankle_pitch"].stiffness == 1.25 and params.aof["ankle_pitch"].damping == 0.5
    assert params.sole_lift_m["aof"] == 0.0123
    assert params.aff == load_params(PARAMS).aff  # the other section is untouched
    comments = lambda text: [line for line in text.splitlines() if line.strip().startswith("#")]  # noqa: E731
    assert comments(after) == comments(before)
    with pytest.raises(InputError, match="no aff.heel"):
        write_params(path, "aff", {"heel": {"stiffness": 1.0, "damping": 1.0}}, 0.0)


def test_calibration_writes_the_parameter_file_and_reports_before_after(tmp_path):
    """Calibration from a wrong start, AFF's sole lift halved (these pitch-plane scenarios hardly
    feel its ankle springs), must bring the foot closer to the closed chain, judged by simulations
    of the rebuilt foot, both on the scenarios it fits and on the one it holds out."""
    params = tmp_path / "params.yaml"
    shutil.copy(PARAMS, params)
    shipped = load_params(PARAMS)
    write_params(params, "aff", {}, shipped.sole_lift_m["aff"] / 2)
    out = tmp_path / "cal"
    # 7 evaluations: the start, the initial simplex's 5 other vertices (the last moves the lift), one step.
    code = main(
        [
            "validate",
            "--variant",
            "aff",
            "--scenarios",
            "flat_2cm",
            "step_toe",
            "rock_front",
            "--calibrate",
            "--evaluations",
            "7",
            "--jobs",
            "2",
            "--params",
            str(params),
            "--out",
            str(out),
        ]
    )
    report = json.loads((out / "report.json").read_text())
    assert code == (0 if report["passed"] else 1)
    cal = report["calibration"]["aff"]
    assert cal["train"] == ["flat_2cm", "step_toe"] and cal["held_out"] == ["rock_front"]
    # The fit's own bookkeeping (objective_after is the best of its history) proves nothing; the
    # feet rebuilt from the written file and run again must beat the runs before calibration,
    # each side computed from its own simulations.
    before, after_runs = cal["series_errors_before"], cal["series_errors_after"]
    for split in ("train", "held_out"):
        assert after_runs[split]["objective"] < before[split]["objective"], (split, before, after_runs)
    written = load_params(params)
    after = cal["parameters_after"]
    assert written.aff["ankle_pitch"].stiffness == after["joints"]["ankle_pitch"]["stiffness"]
    assert written.sole_lift_m["aff"] == after["sole_lift_m"]
    # The reported runs are of the foot rebuilt from the written file.
    assert report["calibration"]["aff"]["series_errors_after"]["train"]["objective"] == pytest.approx(
        cal["objective_after"], rel=1e-6
    )


def test_a_sole_lift_above_the_other_collision_boxes_is_refused(tmp_path, capsys):
    """Where the ankle, arch and roll boxes collide too (collision.upper_collisions), a sole
    lifted above them is refused; where only the sole collides there is nothing to rise above."""
    params = tmp_path / "params.yaml"
    shutil.copy(PARAMS, params)
    write_params(params, "aff", {}, 0.04)
    text = params.read_text()
    assert "  collision: {sole: box, upper_collisions: false}\n" in text
    params.write_text(
        text.replace(
            "  collision: {sole: box, upper_collisions: false}\n",
            "  collision: {sole: box, upper_collisions: true}\n",
            1,
        )
    )
    assert main(["build", "--variant", "aff", "--params", str(params), "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "sole_lift_m 0.04 m raises the aff sole" in err and "keep sole_lift_m below" in err
    assert not (tmp_path / "b").exists()
    params.write_text(text)  # the shipped geometry: only the sole collides
    assert (
        main(["build", "--variant", "aff", "--format", "mjcf", "--params", str(params), "--out", str(tmp_path / "c")])
        == 0
    )


# Forces at the physics rate, obstacles that are hit, and the project's headline claim (issue 15).


@pytest.fixture(scope="module")
def drops():
    """Every variant dropped on flat ground and onto the step under the toe, through the library."""
    return validate(ValidateOptions(variants=("aof", "aff", "ball"), jobs=2, scenarios=("flat_2cm", "step_toe")))


def test_ground_impulse_equals_momentum_change_plus_weight_times_time(drops):
    """From the last sample before contact to the end, the ground's impulse (summed over every
    physics step from contact forces) equals the hanging mass's momentum change (from its
    velocities) plus weight x time: two independent routes to the same number."""
    for variant, runs in drops.runs.items():
        run = runs["flat_2cm"]
        s = run["series"]
        first = int(np.flatnonzero(s["force_z_n"] > 1e-6)[0])
        before = first - 1
        arrival = -s["momentum_z_ns"][before]
        assert arrival > 5.0, variant  # a 13 kg foot and payload falling about 2 cm: about 8 N s
        impulse = float(s["impulse_ns"][first:].sum())
        expected = (
            s["momentum_z_ns"][-1]
            - s["momentum_z_ns"][before]
            + run["supported_weight_n"] * (s["time_s"][-1] - s["time_s"][before])
        )
        assert impulse == pytest.approx(expected, rel=0.01), variant
        # stopping the fall takes at least the arrival momentum (it was 4.91 N s < 8.0 for the ball when sampled)
        assert run["scalars"]["impulse_ns"] > arrival, variant


def test_peak_force_and_impulse_do_not_depend_on_the_recording_interval():
    """The closed chain (0.25 ms step) recorded every 2 ms and every 1 ms: same peak, same impulse."""
    from footforge.timing import StageTimer
    from footforge.validate import simulate
    from footforge.validate.runner import ValidationModels

    models = ValidationModels(ValidateOptions(variants=()), StageTimer(None))
    (case,) = models.cases("full", select(["flat_2cm"]))
    coarse = simulate.run(case, sample_dt_s=0.002)["scalars"]
    fine = simulate.run(case, sample_dt_s=0.001)["scalars"]
    assert fine["peak_force_n"] == pytest.approx(coarse["peak_force_n"], rel=0.02)
    assert fine["impulse_ns"] == pytest.approx(coarse["impulse_ns"], rel=0.02)
    assert coarse["peak_force_n"] > 2 * coarse["final_force_n"]  # an impact, not the settled weight


def test_obstacles_are_hit_or_the_miss_is_reported_and_excluded(drops, quick):
    """The closed chain, AOF and AFF land on every obstacle of the quick set; the ball, a point
    under the middle of the sole, misses the step under the toe, which is then reported and left
    out of its means."""
    _, report, _ = quick
    obstacle_scenarios = [s["name"] for s in report.scenarios if s["obstacle"] not in ("flat", "slope")]
    assert "step_toe" in obstacle_scenarios and len(obstacle_scenarios) >= 3
    for variant in ("full", "aof", "aff"):
        for name in obstacle_scenarios:
            assert report.runs[variant][name]["scalars"]["obstacle_share"] >= fidelity.OBSTACLE_SHARE_MIN, (
                variant,
                name,
            )
    ball = drops.runs["ball"]["step_toe"]["scalars"]
    assert ball["obstacle_share"] < fidelity.OBSTACLE_SHARE_MIN
    summary = drops.fidelity["ball"].summary
    assert summary.missed_obstacle == ["step_toe"]
    assert drops.fidelity["ball"].per_scenario["step_toe"] == {"failed": False, "missed_obstacle": True}
    flat_only = fidelity.errors(drops.runs["ball"]["flat_2cm"], drops.runs["full"]["flat_2cm"])
    assert summary.metrics["final_height_mm"].mean == pytest.approx(flat_only["final_height_mm"])
    assert report.fidelity["ball"].summary.missed_obstacle == ["step_toe"]
    assert (
        "ball: the obstacle carried under 1% of the ground impulse in step_toe" in (quick[2] / "report.md").read_text()
    )


def _obstacle_means(report: ValidationReport, metric: str) -> dict[str, float]:
    """Each variant's mean of `metric` over the obstacle scenarios (slopes included) that every
    variant engaged."""
    fid = report.fidelity
    names = [
        s["name"]
        for s in report.scenarios
        if s["obstacle"] != "flat" and not any(fid[v].per_scenario[s["name"]].get("missed_obstacle") for v in fid)
    ]
    assert len(names) >= 3
    return {v: float(np.mean([fid[v].per_scenario[n][metric] for n in names])) for v in fid}


def test_adaptive_feet_follow_the_closed_chain_closer_than_the_ball_on_obstacles(quick):
    """The project's headline claim on the quick set's obstacles: AOF's and AFF's force curve,
    settled height and centre of pressure are closer to the closed chain's than the ball's."""
    _, report, _ = quick
    for metric in ("force_nrmse", "final_height_mm", "cop_mm"):
        means = _obstacle_means(report, metric)
        assert means["aof"] < means["ball"] and means["aff"] < means["ball"], (metric, means)


@pytest.mark.slow  # the 26 scenarios, about 2.5 min on 2 cores
@pytest.mark.timeout(900)  # explicit budget: several times its time on 2 quiet cores
def test_headline_claim_on_every_obstacle_scenario():
    """The same over all 17 obstacle scenarios that every variant engages, for every metric the
    ball has. AFF's slip error was the one exception (3.2 mm against the ball's 2.9 mm) until its
    recalibration with the passive joints' armature of 1e-3 kg m^2 (2026-11-25: 1.8 mm)."""
    report = validate(ValidateOptions(scenarios=("all",), jobs=2))
    for metric in ("force_nrmse", "peak_force_rel", "final_height_mm", "cop_mm", "slip_mm"):
        means = _obstacle_means(report, metric)
        assert means["aof"] < means["ball"] and means["aff"] < means["ball"], (metric, means)


def test_the_report_names_what_failed(quick):
    _, report, out = quick
    text = (out / "report.md").read_text()
    html_text = (out / "report.html").read_text()
    for variant, f in report.fidelity.items():
        for name, m in f.summary.metrics.items():
            if m.passed is False:
                assert f"{name} " in text.split(f"{variant} fails on:")[1].split("\n")[0], (variant, name)
    assert "`" not in html_text  # markdown code spans became <code>
    verdicts = [f.summary.passed for f in report.fidelity.values()]
    assert html_text.count("<td class='fail'>FAIL</td>") == verdicts.count(False)
    assert html_text.count("<td class='pass'>pass</td>") == verdicts.count(True)


def test_closed_chain_reference_pose_is_at_rest():
    """Released at its reference pose with gravity and contacts off, the closed chain stays put:
    no sole point moves more than 0.1 mm relative to the mount in 1 s (the arch band's rest is the
    pose's arch sum; with rest 0 the sole rose 15.5 mm)."""
    import mujoco

    from footforge.mjcf import foot as foot_lib
    from footforge.mjcf.writing import compile_model
    from footforge.timing import StageTimer
    from footforge.validate.runner import ValidationModels

    full = ValidationModels(ValidateOptions(variants=()), StageTimer(None)).feet["full"]
    model = compile_model(full.mjcf)
    model.opt.timestep = 0.00025  # the drop tests' step for the closed chain
    model.opt.gravity[:] = 0.0
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    data = mujoco.MjData(model)
    for joint, q in full.reference_qpos.items():
        data.qpos[model.jnt_qposadr[model.joint(joint).id]] = q
    mujoco.mj_forward(model, data)
    sole = foot_lib.sole_bodies(full)
    assert len(sole) >= 10  # the chain links
    start = foot_lib.collision_points(model, data, sole)
    for _ in range(int(round(1.0 / model.opt.timestep))):
        mujoco.mj_step(model, data)
    moved = np.linalg.norm(foot_lib.collision_points(model, data, sole) - start, axis=1).max()
    assert moved < 1e-4, f"{moved * 1e3:.3f} mm"


def _conforms(value, schema: dict, root: dict, where: str = "report") -> list[str]:
    """Where `value` breaks the JSON Schema `schema` (the subset json_schema writes: $ref, type,
    properties, required, additionalProperties, items, anyOf)."""
    if "$ref" in schema:
        return _conforms(value, root["$defs"][schema["$ref"].rsplit("/", 1)[1]], root, where)
    if "anyOf" in schema:
        return [] if any(not _conforms(value, s, root, where) for s in schema["anyOf"]) else [f"{where}: {value!r:.60}"]
    kind = schema.get("type")
    ok = {
        None: True,
        "object": isinstance(value, dict),
        "array": isinstance(value, list),
        "string": isinstance(value, str),
        "boolean": isinstance(value, bool),
        "null": value is None,
        "integer": isinstance(value, int) and not isinstance(value, bool),
        "number": isinstance(value, (int, float)) and not isinstance(value, bool),
    }[kind]
    if not ok:
        return [f"{where}: {type(value).__name__} where the schema says {kind}"]
    out = []
    if kind == "object":
        out += [f"{where}: no {k}" for k in schema.get("required", []) if k not in value]
        for k, v in value.items():
            sub = schema.get("properties", {}).get(k, schema.get("additionalProperties"))
            if sub is None:
                out.append(f"{where}: unexpected {k}")
            else:
                out += _conforms(v, sub, root, f"{where}.{k}")
    if kind == "array":
        for i, v in enumerate(value):
            out += _conforms(v, schema["items"], root, f"{where}[{i}]")
    return out


def test_report_json_is_a_typed_report_with_a_shipped_schema(quick):
    """report.json reads back as a ValidationReport and writes out the same; it conforms to the
    JSON Schema shipped with the package, which is the one the typed report generates; a report
    written before reports were typed (the quick set on 2026-11-27) still loads and conforms; and
    the conformance check fails on a report with a wrong type or a missing key."""
    _, report, out = quick
    written = json.loads((out / "report.json").read_text())
    assert json.dumps(report.to_json()) == json.dumps(written)
    schema = json.loads(JSON_SCHEMA_PATH.read_text())
    assert schema == json_schema(), "regenerate footforge/validate/report.schema.json from results.json_schema()"
    assert _conforms(written, schema, schema) == []
    old = json.loads((REPO / "tests/fixtures/validation_report_untyped.json").read_text())
    assert _conforms(old, schema, schema) == []
    loaded = ValidationReport.from_json(old)
    assert loaded.fidelity["ball"].summary.missed_obstacle == ["step_toe"] and loaded.reference.passed
    assert json.dumps(loaded.to_json()) == json.dumps(old)
    broken = json.loads(json.dumps(old))
    broken["speed"]["aof"]["vs_full"] = "fast"
    del broken["reference"]["passed"]
    assert sorted(_conforms(broken, schema, schema)) == [
        "report.reference: no passed",
        "report.speed.aof.vs_full: str where the schema says number",
    ]
