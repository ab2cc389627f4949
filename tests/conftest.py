import atexit
import os
import shutil
import tempfile
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "disable")
# The suite's compiled programs go to a compilation cache of its own (footforge/compile_cache.py),
# shared by its processes (the command-line tests compile the same tiny trainings several times)
# and removed afterwards: a user's cache is neither read nor filled.
_COMPILE_CACHE = tempfile.mkdtemp(prefix="footforge-test-jax-cache-")
os.environ["FOOTFORGE_COMPILE_CACHE"] = _COMPILE_CACHE
atexit.register(shutil.rmtree, _COMPILE_CACHE, ignore_errors=True)

REPO = Path(__file__).resolve().parents[1]
FOOT_XACRO = REPO / "descriptions/softfoot_q/urdf/softfoot_q.urdf.xacro"
FOOT_SIDECAR = REPO / "descriptions/softfoot_q/urdf/softfoot_q.sidecar.yaml"


@pytest.fixture(scope="session")
def built(tmp_path_factory):
    """All four variants built once into a session folder: {variant: (out_dir, report)}."""
    from footforge.build import VARIANTS, BuildOptions, build

    root = tmp_path_factory.mktemp("build")
    cache = tmp_path_factory.mktemp("coacd")
    return {v: (root / v, build(BuildOptions(variant=v, out_dir=root / v, cache_dir=cache))) for v in VARIANTS}
