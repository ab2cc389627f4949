import atexit
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "disable")
# The suite's compiled programs go to a compilation cache of its own (footforge/rl/compile_cache.py),
# used by this process and its subprocesses alike (the command-line tests compile the same tiny
# trainings several times) and removed afterwards: a user's cache is neither read nor filled.
# This differs from a user's CPU policy (footforge/rl/compile_cache.py: off on the CPU unless chosen,
# because reloading a program once crashed XLA:CPU) on purpose: the suite compiles the same programs
# in many processes, and a crash on reload is the suite's to see (every CI run so far has reloaded
# footforge's programs without one), never a user's run to lose.
# FOOTFORGE_TEST_COMPILE_CACHE names a folder to share between pytest sessions instead (CI's
# default and slow runs; .ci/run makes it and removes it).
# pytest-xdist's workers start after this process has read this file and inherit its environment,
# so they share the folder this process makes (and removes).
_SHARED_CACHE = os.environ.get("FOOTFORGE_TEST_COMPILE_CACHE")
_COMPILE_CACHE = _SHARED_CACHE or tempfile.mkdtemp(prefix="footforge-test-jax-cache-")
os.environ["FOOTFORGE_COMPILE_CACHE"] = _COMPILE_CACHE
if not _SHARED_CACHE:
    os.environ["FOOTFORGE_TEST_COMPILE_CACHE"] = _COMPILE_CACHE
    atexit.register(shutil.rmtree, _COMPILE_CACHE, ignore_errors=True)
from footforge.rl import compile_cache  # noqa: E402  (after FOOTFORGE_COMPILE_CACHE is set)

compile_cache.enable()

REPO = Path(__file__).resolve().parents[1]
FOOT_XACRO = REPO / "descriptions/softfoot_q/urdf/softfoot_q.urdf.xacro"
FOOT_SIDECAR = REPO / "descriptions/softfoot_q/urdf/softfoot_q.sidecar.yaml"


@pytest.fixture(scope="session")
def coacd_cache(tmp_path_factory):
    """The suite's own CoACD cache folder (a user's is neither read nor filled)."""
    return tmp_path_factory.mktemp("coacd")


class _Builds(Mapping):
    """{variant: (out_dir, build report)}, each variant built when a test first asks for it, once
    per test session: under pytest-xdist into a folder of the session that every worker shares, the
    first worker to ask building it under a lock while the others wait for it (the closed chain's
    build takes about 20 s on 2 cores, and a worker whose files never ask for a variant skips it)."""

    def __init__(self, root: Path, coacd_cache: Path):
        self._root, self._coacd_cache = root, coacd_cache
        self._got: dict = {}

    def __getitem__(self, variant):
        import fcntl
        import json

        from footforge.build import VARIANTS, BuildOptions, build

        if variant not in VARIANTS:
            raise KeyError(variant)
        if variant not in self._got:
            out, done = self._root / variant, self._root / f"{variant}.done"
            with open(self._root / f"{variant}.lock", "w") as lock:
                fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
                if not done.exists():
                    build(BuildOptions(variant=variant, out_dir=out, cache_dir=self._coacd_cache))
                    done.touch()
            self._got[variant] = (out, json.loads((out / "build_report.json").read_text()))
        return self._got[variant]

    def __iter__(self):
        from footforge.build import VARIANTS

        return iter(VARIANTS)

    def __len__(self):
        from footforge.build import VARIANTS

        return len(VARIANTS)


@pytest.fixture(scope="session")
def built(tmp_path_factory, coacd_cache):
    """Every variant's build, made on first use (_Builds): {variant: (out_dir, report)}, the report
    as build_report.json holds it."""
    if os.environ.get("PYTEST_XDIST_WORKER"):  # the workers' base folders share this session's parent
        root = tmp_path_factory.getbasetemp().parent / "shared-builds"
        root.mkdir(exist_ok=True)
    else:
        root = tmp_path_factory.mktemp("build")
    return _Builds(root, coacd_cache)


_FLOAT64_STANCE = """
import dataclasses, json, sys
import jax
from footforge.validate.stance import env_stance, env_stance_start
task, feet, build_root = sys.argv[1], sys.argv[2], sys.argv[3]
env, state = env_stance_start(task, feet, build_root + "/" + feet, float64_physics=True)
step = jax.jit(env.step)
after = step(state, jax.numpy.zeros(env.action_size))
print(json.dumps(dataclasses.asdict(env_stance(env, state, seconds=10.0, step=step)) | {
    "physics": str(after.pipeline_state.qpos.dtype), "obs": str(after.obs.dtype), "reward": str(after.reward.dtype),
    "metrics": sorted({str(v.dtype) for v in after.metrics.values()})}))
"""


def float64_stance(task: str, feet: str, build_root) -> dict:
    """footforge.validate.stance.env_stance over 10 s in a subprocess with float64 physics (x64 is
    process-wide), and the dtypes the policy's side sees."""
    import json
    import subprocess
    import sys

    # A float64 value scattered into a float32 array warns now and will be an error in JAX.
    run = subprocess.run(
        [
            sys.executable,
            "-W",
            "error:scatter inputs have incompatible types:FutureWarning",
            "-c",
            _FLOAT64_STANCE,
            task,
            feet,
            str(build_root),
        ],
        capture_output=True,
        text=True,
        timeout=1500,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


HEAVIEST_FIRST = (
    "test_shipped_policies.py",
    "test_rough.py",
    "test_engines.py",
    "test_train.py",
    "test_envs.py",
    "test_closed_chain.py",
    "test_cli.py",
    "test_export.py",
    "test_validate.py",
    "test_play.py",
)
"""Test files with the longest default runs (40-100 s each on 2 cores, 2026-11-29), heaviest first.
pytest-xdist (`--dist loadfile`) hands whole files to its two workers in collection order; started
first, the long files end together instead of one of them running on alone at the end."""


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(HEAVIEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the rest keep their order
