"""Packaging: pyproject.toml's requirements against constraints.txt (the tested lock), the build
extra against what footforge.extras checks, and the commands that need the build extra refusing
without it (exit 2, the install command, no traceback) while the rest runs without it."""

import os
import subprocess
import sys
import tomllib

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from footforge.cli.main import main
from footforge.errors import InputError

from conftest import REPO

PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
INSTALL = 'pip install "footforge[build]"'


def _pins() -> dict[str, str]:
    pins = {}
    for line in (REPO / "constraints.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            name, version = line.split("==")
            pins[canonicalize_name(name)] = version
    return pins


def _requirements() -> list[Requirement]:
    extras = [r for group in PROJECT["optional-dependencies"].values() for r in group]
    return [Requirement(r) for r in PROJECT["dependencies"] + extras]


def test_every_requirement_has_a_lower_bound_that_its_pin_in_constraints_meets():
    pins, problems = _pins(), []
    for req in _requirements():
        name = canonicalize_name(req.name)
        if name == "footforge":  # test's footforge[build]
            continue
        if not any(s.operator == ">=" for s in req.specifier) or any(s.operator == "==" for s in req.specifier):
            problems.append(f"{req}: a lower bound, not a pin (constraints.txt pins)")
        elif name not in pins:
            problems.append(f"{req}: not pinned in constraints.txt")
        elif pins[name] not in req.specifier:
            problems.append(f"{req}: constraints.txt's {pins[name]} does not meet it")
    assert not problems, "\n".join(problems)


def test_the_build_extra_is_what_footforge_extras_checks_and_the_tests_install_it():
    from footforge.extras import BUILD_EXTRA

    listed = {canonicalize_name(Requirement(r).name) for r in PROJECT["optional-dependencies"]["build"]}
    assert listed == {canonicalize_name(d) for d in BUILD_EXTRA.values()}
    assert "footforge[build]" in PROJECT["optional-dependencies"]["test"]
    core = {canonicalize_name(Requirement(r).name) for r in PROJECT["dependencies"]}
    assert not core & listed


@pytest.mark.parametrize(
    "argv", [["build", "--variant", "aof"], ["validate", "--variant", "aff"], ["check", "foot.urdf"]]
)
def test_a_job_of_the_build_extra_without_it_names_the_extra_and_exits_2(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "coacd", None)  # as a core install lacks it: `import coacd` raises
    monkeypatch.setitem(sys.modules, "pxr", None)
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith(f"footforge {argv[0]}: error: footforge {argv[0]} needs footforge's build extra")
    assert "usd-core, coacd missing" in err and INSTALL in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())  # nothing written (no build/, no validation/)


def test_a_first_use_build_without_the_extra_names_it_and_the_way_around(tmp_path, monkeypatch):
    from footforge.cli.builds import build_defaults_if_missing

    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "dm_control", None)
    with pytest.raises(InputError) as refused:
        build_defaults_if_missing(["aof"], None)
    text = str(refused.value)
    assert refused.value.exit_code == 2 and "build/aof holds no model" in text
    assert "dm-control missing" in text and INSTALL in text and "--build-root" in text
    assert not (tmp_path / "build").exists()


def test_training_evaluation_export_and_play_import_without_the_build_extra():
    """What a core install (`pip install footforge`) lacks cannot be imported here, in a fresh
    process: every command's help still shows, the library's training side imports, and
    `footforge build` refuses by name. (trimesh, scipy and PyYAML stay: MJX, JAX and flax need them.)"""
    code = """
import sys
for name in ("dm_control", "xacro", "pxr", "coacd", "fast_simplification", "pinocchio", "lxml"):
    sys.modules[name] = None
import footforge.envs, footforge.rl.train, footforge.rl.evaluate, footforge.rl.evaluate_closed_chain
import footforge.rl.play, footforge.rl.export_onnx, footforge.rl.policy_files
from footforge.cli.main import main, parsers
parsers()
assert main(["--help"]) == 0
assert main(["build", "--variant", "aof"]) == 2
"""
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
        env={**os.environ, "MUJOCO_GL": "disable"},
    )
    assert out.returncode == 0, out.stderr
    assert "footforge build: error: footforge build needs footforge's build extra" in out.stderr
    assert INSTALL in out.stderr and "Traceback" not in out.stderr
