"""The command line: exit codes, messages that name file/element/fix, no partial output."""

import math
import re
import shutil

import numpy as np
import pytest
import yaml

from footforge.cli.main import main

from conftest import FOOT_SIDECAR, FOOT_XACRO, REPO


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out + out.err


@pytest.fixture
def foot_copy(tmp_path):
    """A copy of the SoftFoot-Q description (xacro, sidecar, meshes) to plant defects in."""
    pkg = tmp_path / "softfoot_q"
    shutil.copytree(REPO / "descriptions/softfoot_q", pkg)
    return pkg


def test_build_writes_outputs_and_summary(capsys, tmp_path):
    code, text = run(capsys, "build", "--variant", "aff", "--out", tmp_path / "out", "--cache-dir", tmp_path / "c")
    assert code == 0, text
    assert "total mass" in text and "pass" in text
    assert {p.name for p in (tmp_path / "out").iterdir()} == {
        "robot.xml",
        "scene.xml",
        "foot_rig.xml",
        "assets",
        "build_report.json",
        "robot.usda",
        "robot.usd",
        "foot_rig.usda",
        "foot_rig.usd",
        ".footforge-output",
    }


def test_foot_only(capsys, tmp_path):
    code, text = run(
        capsys, "build", "--variant", "aof", "--foot-only", "--out", tmp_path / "f", "--cache-dir", tmp_path / "c"
    )
    assert code == 0, text
    assert (tmp_path / "f/foot.xml").is_file() and not (tmp_path / "f/robot.xml").exists()


def test_unknown_variant_is_a_usage_error(capsys):
    code, text = run(capsys, "build", "--variant", "hoof")
    assert code == 2 and "invalid choice" in text


def test_missing_mesh_names_link_and_leaves_no_output(capsys, tmp_path, foot_copy):
    (foot_copy / "meshes/arch.stl").unlink()
    out = tmp_path / "out"
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aof",
        "--description",
        foot_copy / "urdf/softfoot_q.urdf.xacro",
        "--package-path",
        tmp_path,
        "--out",
        out,
    )
    assert code == 2
    assert "arch.stl" in text and "front_arch" in text and "fix:" in text and "Traceback" not in text
    assert not out.exists() and not any(p.name.startswith(".out.tmp") for p in tmp_path.iterdir())


def _flat_stl(path):
    """A 5 cm square of two triangles: a mesh with area but no volume."""
    import trimesh

    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 0.05
    trimesh.Trimesh(square, [[0, 1, 2], [0, 2, 3]], process=False).export(path)


def test_a_flat_collision_mesh_is_found_by_check_and_refused_by_build(capsys, tmp_path, foot_copy):
    """A degenerate (flat) collision mesh: `check` reports it (it used to say "no findings"), and the
    build refuses it in its description check, before CoACD, with the file named (exit 1, a check
    failure; it used to crash in trimesh, needing networkx)."""
    _flat_stl(foot_copy / "meshes/arch.stl")
    xacro = foot_copy / "urdf/softfoot_q.urdf.xacro"
    code, text = run(capsys, "check", xacro, "--package-path", tmp_path)
    assert code == 1 and "unusable_collision_mesh" in text and "arch.stl" in text and "flat" in text
    out = tmp_path / "out"
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aof",
        "--description",
        xacro,
        "--package-path",
        tmp_path,
        "--out",
        out,
        "--cache-dir",
        tmp_path / "c",
    )
    assert code == 1 and "unusable_collision_mesh" in text and "arch.stl" in text
    assert "Traceback" not in text and "networkx" not in text
    assert not out.exists()


def test_malformed_xacro(capsys, tmp_path, foot_copy):
    path = foot_copy / "urdf/softfoot_q.xacro"
    path.write_text(path.read_text().replace("</robot>", "</robt>"))
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aff",
        "--description",
        foot_copy / "urdf/softfoot_q.urdf.xacro",
        "--package-path",
        tmp_path,
        "--out",
        tmp_path / "out",
    )
    assert code == 2 and ("malformed" in text.lower() or "xacro failed" in text), text
    assert "Traceback" not in text


def test_unresolved_package(capsys, tmp_path):
    urdf = tmp_path / "foot.urdf"
    urdf.write_text(
        '<robot name="r"><link name="a"><visual><geometry><mesh filename="package://nopkg/m.stl"/>'
        "</geometry></visual></link></robot>"
    )
    code, text = run(capsys, "check", urdf)
    assert code == 1 and "nopkg" in text


def test_non_physical_inertia_fails_then_repairs(capsys, tmp_path, foot_copy):
    path = foot_copy / "urdf/softfoot_q.xacro"
    path.write_text(path.read_text().replace('izz="4.0468e-6"', 'izz="1.0468e-6"'))  # the public file's typo
    args = [
        "build",
        "--variant",
        "aff",
        "--description",
        foot_copy / "urdf/softfoot_q.urdf.xacro",
        "--package-path",
        tmp_path,
        "--cache-dir",
        tmp_path / "c",
    ]
    code, text = run(capsys, *args, "--out", tmp_path / "out")
    assert code == 1 and "ankle" in text and "triangle" in text and "--repair" in text
    assert not (tmp_path / "out").exists()
    code, text = run(capsys, *args, "--out", tmp_path / "out", "--repair")
    assert code == 0, text
    report = (tmp_path / "out/build_report.json").read_text()
    assert "inertia balanced" in report


def test_check_finds_crossed_closure(capsys, tmp_path):
    """The reference sheet's '∓' for the back insertion points crosses the side chains (in the back
    roll link's frame, turned by pi about z, the right chain ends at +y): check must say so."""
    data = yaml.safe_load(FOOT_SIDECAR.read_text())
    for closure in data["closures"]:
        closure["to_point"][1] = -closure["to_point"][1]
    sidecar = tmp_path / "crossed.sidecar.yaml"
    sidecar.write_text(yaml.safe_dump(data))
    code, text = run(capsys, "check", FOOT_XACRO, "--sidecar", sidecar)
    assert code == 1 and "closure" in text and "does not close" in text


def test_closure_axis_off_the_chain_pins_is_refused(capsys, tmp_path):
    """A closure whose pin axis is not its chain's (turned 10 degrees about z in the link's frame)
    cannot be closed by a point coincidence alone: check reports it and build refuses it, naming
    the closure; the shipped axes lie on the pins (0 degrees)."""
    data = yaml.safe_load(FOOT_SIDECAR.read_text())
    closure = data["closures"][1]
    assert closure["axis"] == [1.0, 0.0, 0.0]
    closure["axis"] = [math.cos(math.radians(10)), math.sin(math.radians(10)), 0.0]
    sidecar = tmp_path / "tilted.sidecar.yaml"
    sidecar.write_text(yaml.safe_dump(data))
    code, text = run(capsys, "check", FOOT_XACRO, "--sidecar", sidecar)
    assert code == 1 and f"closure '{closure['name']}'" in text and "10.0 deg off" in text, text
    code, text = run(
        capsys, "build", "--variant", "aof", "--sidecar", sidecar, "--out", tmp_path / "o", "--format", "mjcf"
    )
    assert code == 1 and "10.0 deg off" in text and not (tmp_path / "o").exists(), text


def test_check_clean_descriptions(capsys):
    code, text = run(capsys, "check", FOOT_XACRO, "--sidecar", FOOT_SIDECAR)
    assert code == 0, text
    code, text = run(
        capsys, "check", REPO / "descriptions/anymal_c/urdf/anymal_c.urdf.xacro", "--arg", "foot:=softfoot_q"
    )
    assert code == 0, text


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda d: d.update(friction=-1), "friction"),
        (lambda d: d.update(bogus=1), "top level: unknown keys ['bogus']"),
        (lambda d: d["closures"][0].update(link="no_such_link"), "no_such_link"),
    ],
)
def test_bad_sidecar_values(capsys, tmp_path, edit, message):
    data = yaml.safe_load(FOOT_SIDECAR.read_text())
    edit(data)
    sidecar = tmp_path / "bad.sidecar.yaml"
    sidecar.write_text(yaml.safe_dump(data))
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aff",
        "--sidecar",
        sidecar,
        "--out",
        tmp_path / "o",
        "--cache-dir",
        tmp_path / "c",
    )
    text = " ".join(text.split())  # rich wraps long lines where the temporary path's length puts them
    assert code == 2 and message in text and "Traceback" not in text


def test_bad_params_and_args(capsys, tmp_path):
    params = yaml.safe_load((REPO / "descriptions/softfoot_q/config/variant_params.yaml").read_text())
    params["full"]["closure_solref"] = [0.0001, 1.0]
    p = tmp_path / "params.yaml"
    p.write_text(yaml.safe_dump(params))
    code, text = run(capsys, "build", "--variant", "full", "--params", p, "--out", tmp_path / "o")
    assert code == 2 and "timeconst" in text
    code, text = run(capsys, "build", "--variant", "aff", "--arg", "novalue", "--out", tmp_path / "o")
    assert code == 2 and "NAME:=VALUE" in text
    for fmt in (None, 2):  # a parameter file without its format, or of another one
        other = {k: v for k, v in params.items() if k != "format"} | ({"format": fmt} if fmt else {})
        p.write_text(yaml.safe_dump(other))
        code, text = run(capsys, "build", "--variant", "aff", "--params", p, "--out", tmp_path / "o")
        assert code == 2 and "format" in text and not (tmp_path / "o").exists(), text


def test_version(capsys):
    import footforge

    code, text = run(capsys, "--version")
    assert code == 0 and text.startswith(f"footforge {footforge.__version__} (mujoco ")


def test_pipelines_build_the_default_builds_once(tmp_path, monkeypatch):
    """Without --build-root the pipelines make build/<feet>/ where it is missing, and leave an
    existing one alone; with a build root of the user's they build nothing."""
    from footforge.cli.builds import build_defaults_if_missing

    monkeypatch.chdir(tmp_path)
    build_defaults_if_missing(["ball"], tmp_path / "mine")
    assert not (tmp_path / "build").exists() and not (tmp_path / "mine").exists()
    build_defaults_if_missing(["ball", "ball"], None)
    scene = tmp_path / "build" / "ball" / "scene.xml"
    assert scene.is_file()
    built_at = scene.stat().st_mtime_ns
    build_defaults_if_missing(["ball"], None)
    assert scene.stat().st_mtime_ns == built_at


def test_existing_default_builds_need_no_build_packages(tmp_path, monkeypatch):
    """The offline GPU machine trains from builds made beforehand and has none of the build's
    packages (lxml, xacro, coacd, pinocchio): with build/<feet>/ present, the pipelines' first-use
    check imports none of them."""
    import subprocess
    import sys

    (tmp_path / "build" / "ball").mkdir(parents=True)
    (tmp_path / "build" / "ball" / "scene.xml").write_text("<mujoco/>")
    code = (
        "import sys; sys.modules.update(lxml=None, xacro=None, coacd=None, pinocchio=None); "
        "from footforge.cli.builds import build_defaults_if_missing; "
        "build_defaults_if_missing(['ball'], None); print('ok')"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


# --- one command for every job: footforge <job>, and pipelines/*.py as its shims ---

JOBS = ("build", "validate", "check", "train", "evaluate", "evaluate-closed-chain", "play", "export")


def test_help_lists_every_job_in_one_line_each(capsys):
    code, text = run(capsys, "--help")
    assert code == 0
    listed = [line.split()[0] for line in text.splitlines() if line.startswith("    ") and line.split()]
    assert [job for job in listed if job in JOBS] == list(JOBS)


@pytest.mark.parametrize(
    "job, first_option",
    [
        ("evaluate", "--policy"),
        ("evaluate-closed-chain", "--robots"),
        ("play", "--headless"),
        ("train flat", "--feet"),
        ("train rough", "--terrain"),
    ],
)
def test_each_job_has_its_own_help(capsys, job, first_option):
    code, text = run(capsys, *job.split(), "--help")
    assert code == 0 and f"usage: footforge {job} " in text and first_option in text


def test_train_without_a_task_is_a_usage_error(capsys):
    code, text = run(capsys, "train", "--feet", "ball", "--out", "runs/x")
    assert code == 2 and "one of flat, rough" in text and "(got '--feet')" in text
    code, text = run(capsys, "train", "--help")
    assert code == 0 and "footforge train {flat,rough}" in text


def test_a_job_reports_bad_input_with_its_exit_code(capsys, tmp_path):
    """The delegated jobs keep their own checks: a policy folder that does not exist is exit 2."""
    code, text = run(capsys, "evaluate", "--policy", tmp_path / "none", "--out", tmp_path / "eval")
    assert code == 2 and f"{tmp_path / 'none'}" in text and not (tmp_path / "eval").exists()


@pytest.mark.parametrize(
    "job, argv",
    [
        ("export", ["export", "{missing}"]),
        ("evaluate", ["evaluate", "--policy", "{missing}", "--out", "{out}"]),
        ("evaluate-closed-chain", ["evaluate-closed-chain", "--policy", "{missing}", "--out", "{out}"]),
        ("play", ["play", "{missing}", "--headless"]),
        ("train flat", ["train", "flat", "--out", "{missing}", "--resume"]),
        ("validate", ["validate", "--variant", "aof", "--params", "{missing}"]),
    ],
)
def test_every_command_s_error_starts_with_its_own_name(capsys, tmp_path, job, argv):
    """One error prefix for every command, `footforge <command>: error:`, whichever module runs it
    (issue: `footforge: error:`, `evaluate: error:`, `play: error:`, `train_flat: error:`)."""
    argv = [a.format(missing=tmp_path / "missing", out=tmp_path / "out") for a in argv]
    code, text = run(capsys, *argv)
    errors = [line for line in text.splitlines() if ": error: " in line]
    assert code == 2 and errors and errors[0].startswith(f"footforge {job}: error: "), text


def test_every_command_is_a_module_with_parser_and_run_and_one_error_path():
    """Each command of `footforge --help` is a module of footforge/cli/ with parser(prog) and run(args)
    (footforge.cli.command), and only footforge.cli.command turns errors and interrupts into exit
    codes: no command module catches FootforgeError or KeyboardInterrupt itself."""
    import inspect

    from footforge.cli.command import COMMANDS, module
    from footforge.cli.main import _parser

    listed = next(a for a in _parser()._actions if a.dest == "command").choices
    assert list(listed) == list(COMMANDS)
    for name in COMMANDS:
        command = module(name)
        assert list(inspect.signature(command.run).parameters) == ["args"], name
        assert next(iter(inspect.signature(command.parser).parameters)) == "prog", name
    catchers = [
        path.name
        for path in (REPO / "footforge" / "cli").glob("*.py")
        if path.name != "command.py" and re.search(r"except[^:\n]*(FootforgeError|KeyboardInterrupt)", path.read_text())
    ]
    assert catchers == []


def test_an_interrupted_command_says_what_it_left_and_exits_130(monkeypatch, capsys, tmp_path):
    """Ctrl-C in a command's work: one line naming what it left (a training run its checkpoints, the
    viewer nothing: exit 0) and the shell's code for an interrupt."""
    from footforge.cli import command, export, play

    def interrupt(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(export, "run", interrupt)
    assert command.run_command(export, [str(tmp_path)], "footforge export") == 130
    assert capsys.readouterr().err == "footforge export: interrupted; no output was written\n"
    monkeypatch.setattr(play, "run", interrupt)
    assert command.run_command(play, [str(tmp_path)], "footforge play") == 0  # leaving the viewer
    assert command.run_command(play, [str(tmp_path), "--headless"], "footforge play") == 130
    assert capsys.readouterr().err == "footforge play: interrupted; no video or log was written\n"


@pytest.mark.parametrize(
    "script, job",
    [
        ("evaluate", "evaluate"),
        ("evaluate_closed_chain", "evaluate-closed-chain"),
        ("play", "play"),
        ("train_flat", "train flat"),
        ("train_rough", "train rough"),
    ],
)
def test_pipeline_scripts_run_the_same_jobs(script, job):
    """pipelines/<script>.py, run by path as people do, is footforge <job>: the same options."""
    import subprocess
    import sys

    def options(cmd):
        out = subprocess.run(cmd + ["--help"], capture_output=True, text=True, cwd=REPO, timeout=120)
        assert out.returncode == 0, out.stderr
        return sorted({word.strip("[],") for word in out.stdout.split() if word.startswith(("--", "[--"))})

    assert options([sys.executable, str(REPO / "pipelines" / f"{script}.py")]) == options(
        [sys.executable, "-m", "footforge.cli", *job.split()]
    )


def test_every_option_of_every_job_says_what_it_does_and_its_default():
    """Each option has help; an option with a default value (not a flag, not None for "not given")
    shows that value in its help."""
    import argparse

    from footforge.cli.main import parsers

    jobs = parsers()
    assert set(jobs) == {
        "build",
        "validate",
        "check",
        "export",
        "evaluate",
        "evaluate-closed-chain",
        "play",
        "train flat",
        "train rough",
    }
    missing = []
    for job, parser in jobs.items():
        assert parser.description, job
        text = parser.format_help()
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            name = "/".join(action.option_strings) or action.dest
            if not action.help:
                missing.append(f"{job} {name}: no help")
            elif (
                action.option_strings
                and action.default not in (None, [], argparse.SUPPRESS)
                and not isinstance(action.default, bool)
            ):
                values = action.default if isinstance(action.default, list) else [action.default]
                flat = " ".join(text.split())
                for value in map(str, values):  # 10.0 may be written 10
                    if value not in flat and (value.rstrip("0").rstrip(".") if "." in value else value) not in flat:
                        missing.append(f"{job} {name}: default {value} not shown")
    assert not missing, "\n".join(missing)


def _named_defaults(job: str) -> dict[str, list]:
    """Per option, the configuration defaults its help names where argparse holds none (or holds a
    copy): the dataclass field (or module constant) each stands for."""
    from footforge.envs.config import EnvConfig
    from footforge.models.collision import DecompositionConfig
    from footforge.rl.config import default_ppo
    from footforge.rl.evaluate import SECONDS
    from footforge.rl.play import PlayConfig

    decomposition = DecompositionConfig()
    named: dict[str, dict[str, list]] = {
        "build": {
            "--max-hull-vertices": [decomposition.max_hull_vertices],
            "--coacd-timeout": [decomposition.timeout_s],
            "--face-budget": [decomposition.face_budget],
        },
        "evaluate": {"--seconds": list(SECONDS.values())},
        "play": {"--seed": [PlayConfig.seed]},
    }
    named["validate"] = {k: v for k, v in named["build"].items()}
    for task in ("flat", "rough"):
        ppo, env = default_ppo(task), EnvConfig()
        named[f"train {task}"] = {
            "--feet": [env.feet],
            "--policy": [env.policy],
            "--num-envs": [ppo.num_envs],
            "--timesteps": [ppo.num_timesteps],
            "--seed": [ppo.seed],
            "--unroll-length": [ppo.unroll_length],
            "--batch-size": [ppo.batch_size],
            "--minibatches": [ppo.num_minibatches],
            "--checkpoint-every": [ppo.checkpoint_every_steps],
            "--eval-envs": [ppo.num_eval_envs],
            "--contact-model": [env.contact_model],
            "--mjx-impl": [env.mjx_impl],
        }
    return named.get(job, {})


_FIGURE = re.compile(r"(?<![\w.])-?\d[\d,]*(?:\.\d+)?(?:e[+-]?\d+)?(?![\w])")


def test_every_default_a_help_names_is_the_one_in_use():
    """Each figure in an option's '(default ...)' (up to a bracket, ';' or ':') is the option's
    argparse default or the configuration default it stands for (_named_defaults: EnvConfig,
    PPOConfig through default_ppo, DecompositionConfig, PlayConfig, rl.evaluate.SECONDS), so a
    default changed in a dataclass cannot leave a stale figure in --help; where an option stands
    for a dataclass field, its argparse default (if any) is that field's and its help names it."""
    import argparse

    from footforge.cli.main import parsers

    wrong, checked = [], 0
    for job, parser in parsers().items():
        named = _named_defaults(job)
        formatter = parser._get_formatter()
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction) or not action.help or action.help == argparse.SUPPRESS:
                continue
            name = action.option_strings[0] if action.option_strings else action.dest
            text = (
                " ".join(formatter._expand_help(action).split())
                if "%(" in action.help
                else " ".join(action.help.split())
            )
            if action.option_strings and "default" not in text.lower() and "%(default)" not in action.help:
                text = " ".join(formatter._get_help_string(action).replace("%(default)s", str(action.default)).split())
            defaults = action.default if isinstance(action.default, (list, tuple)) else [action.default]
            allowed = [d for d in [*defaults, *named.get(name, [])] if d is not None and not isinstance(d, bool)]
            for phrase in re.findall(r"default:?[^);:]*", text, flags=re.IGNORECASE):
                for figure in _FIGURE.findall(phrase):
                    checked += 1
                    value = float(figure.replace(",", ""))
                    if not any(isinstance(d, (int, float)) and math.isclose(value, d) for d in allowed):
                        wrong.append(f"{job} {name}: '{figure}' in \"{phrase}\" is none of {allowed}")
            for value in named.get(name, []):
                if action.default not in (None, [], argparse.SUPPRESS) and action.default != value:
                    wrong.append(f"{job} {name}: argparse default {action.default!r}, the configuration's {value!r}")
                shown = (
                    f"{value:,}"
                    if isinstance(value, int) and value >= 10_000
                    else f"{value:g}"
                    if isinstance(value, float)
                    else str(value)
                )
                if len(named[name]) == 1 and shown not in text and str(value) not in text:
                    wrong.append(f"{job} {name}: the help does not name its default {value!r}: {text!r}")
    assert checked > 20  # the figures are found at all
    assert not wrong, "\n".join(wrong)


def test_commands_hold_back_mjx_s_lines_about_a_missing_warp():
    """`import mujoco.mjx` (Brax imports it too) prints two lines about warp-lang where it is
    missing; footforge's commands hold exactly those back (footforge._QuietMjxWarp), and the
    module still imports whole."""
    import subprocess
    import sys

    code = (
        "import footforge; footforge.headless_by_default(); footforge.headless_by_default(); "
        "import brax.envs.base; from mujoco.mjx import warp; print('imported', warp.WARP_INSTALLED in (True, False))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout == "imported True\n" and "Failed to import" not in out.stderr
    import footforge

    assert sum(isinstance(f, footforge._QuietMjxWarp) for f in sys.meta_path) <= 1


def test_tables_are_not_cut_when_piped(monkeypatch):
    """Printed into a pipe or a log, a table as wide as validate's keeps every header whole
    (rich would cut it to 80 columns: 'varia… force…')."""
    import io

    from rich.table import Table

    from footforge.cli.help import PIPED_WIDTH, console

    monkeypatch.delenv("COLUMNS", raising=False)
    out = console()
    assert not out.is_terminal and out.width == PIPED_WIDTH  # pytest captures: not a terminal
    headers = [
        "variant",
        "force_nrmse",
        "peak_force_rel",
        "final_height_mm",
        "orientation_deg",
        "cop_mm",
        "slip_mm",
        "speed vs full",
        "verdict",
    ]
    table = Table()
    for h in headers:
        table.add_column(h)
    table.add_row("aff", *["0.123"] * 7, "FAIL")
    out.file = io.StringIO()
    out.print(table)
    text = out.file.getvalue()
    assert "…" not in text and all(h in text for h in headers)


@pytest.mark.parametrize("value", ["bogus", "Egl"])
def test_an_unknown_mujoco_gl_is_an_input_error_for_every_command(value):
    """MUJOCO_GL with a value MuJoCo or dm_control rejects ('Egl': dm_control compares it as written)
    made `import mujoco` raise a traceback from every command, --help included: now each command
    and each pipelines/ script refuses it first, exit 2, one line naming the value and the accepted
    ones. The control: the same commands with MUJOCO_GL=disable print their help (exit 0)."""
    import os
    import subprocess
    import sys

    commands = [
        ["-m", "footforge.cli.main", "--help"],
        ["-m", "footforge.cli.main", "build", "--help"],
        ["-m", "footforge.cli.main", "train", "flat", "--help"],
        ["-m", "footforge.cli.main", "evaluate", "--help"],
        ["-m", "footforge.cli.main", "play", "--help"],
        ["-m", "footforge.cli.main", "evaluate-closed-chain", "--help"],
        [str(REPO / "pipelines" / "train_rough.py"), "--help"],
    ]
    for command in commands:
        for setting, code in ((value, 2), ("disable", 0)):
            done = subprocess.run(
                [sys.executable, *command],
                capture_output=True,
                text=True,
                timeout=300,
                env=os.environ | {"MUJOCO_GL": setting},
            )
            assert done.returncode == code, (command, setting, done.stderr[-2000:])
            if code == 2:
                assert "Traceback" not in done.stderr and done.stderr.count("\n") == 1, (command, done.stderr)
                assert f"MUJOCO_GL={value!r}" in done.stderr and "'egl'" in done.stderr and "unset it" in done.stderr
                # One prefix: the command's own words (`footforge evaluate: error:`), `footforge:` for the bare one.
                words = [w for w in command[2:] if not w.startswith("-")] if command[0] == "-m" else []
                prefix = " ".join(["footforge", *words]) if command[0] == "-m" else "footforge train rough"
                assert done.stderr.startswith(f"{prefix}: error: "), (prefix, done.stderr)


def test_the_cpu_learning_benchmark_says_whole_sentences_and_writes_valid_json():
    """benchmarks/learning_cpu.py: its --help gives the docstring's first paragraph whole (it stopped
    mid-sentence), and its result line is JSON whatever could not be measured (vx_slope was NaN)."""
    import importlib.util
    import json
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, str(REPO / "benchmarks/learning_cpu.py"), "--help"],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    description = " ".join(out.stdout.split("\n\n")[1].split())
    assert description.endswith(".") and "a variant of its settings" in description, description
    spec = importlib.util.spec_from_file_location("learning_cpu", REPO / "benchmarks/learning_cpu.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    row = {"vx_slope": float("nan"), "gait": {"trot": float("inf")}, "curve": [{"x": 1.5}], "steps": 3}
    assert json.loads(json.dumps(module._finite_or_none(row), allow_nan=False)) == {
        "vx_slope": None,
        "gait": {"trot": None},
        "curve": [{"x": 1.5}],
        "steps": 3,
    }
