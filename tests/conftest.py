import os
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "disable")

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
