"""ANYmal C description (descriptions/anymal_c) against the published fused rigid-body listing.

The xacro is expanded, imported into MuJoCo with fixed joints fused (as the listing was made), and
every body, joint and collision geom is compared numerically with the listing, which is kept below
verbatim as literal data (ANYbotics' "ANYmal C simple description", BSD-3-Clause, as compiled by
MuJoCo). Pinocchio cross-checks the frames, limits and total mass.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import xacro
from lxml import etree

DESCRIPTION = Path(__file__).resolve().parents[1] / "descriptions" / "anymal_c"
XACRO_FILE = DESCRIPTION / "urdf" / "anymal_c.urdf.xacro"

LEGS = ("LF", "RF", "LH", "RH")
MOVING_LINKS = {"base"} | {f"{leg}_{part}" for leg in LEGS for part in ("HIP", "THIGH", "SHANK")}
TOTAL_MASS = 52.13485  # kg, with the ball feet
BALL_Z = 0.0225  # ball centre above FOOT

# Published ground truth: MuJoCo's listing of the fused rigid bodies of the reference description
# (pos/quat: body in parent, quat w x y z; ipos/iquat: COM and principal axes in the body frame;
# inertia: principal moments; geom types 2 sphere, 5 cylinder [radius, half-length], 6 box
# [half-extents]). Verbatim, rounded as published.
REFERENCE_LISTING = """
nbody 14 njnt 13 total mass 52.134850000000014
BODY world (world)
BODY base parent=world pos=[0. 0. 0.] quat=[1. 0. 0. 0.] mass=26.37317 ipos=[-0.01779 -0.00018  0.0085 ] iquat=[-0.00383  0.71958 -0.00775  0.69436] inertia=[1.83725 1.78446 0.21386]
   JOINT floating_base type=0 axis=[0. 0. 1.] pos=[0. 0. 0.] range=[0. 0.] limited=False
   GEOM type=6 size=[0.29 0.07 0.09] pos=[0. 0. 0.] quat=[1. 0. 0. 0.]
   GEOM type=5 size=[0.09   0.0725 0.    ] pos=[0.2175 0.07   0.    ] quat=[0.70711 0.      0.70711 0.     ]
   GEOM type=5 size=[0.09   0.0725 0.    ] pos=[-0.2175  0.07    0.    ] quat=[0.70711 0.      0.70711 0.     ]
   GEOM type=5 size=[0.09   0.0725 0.    ] pos=[ 0.2175 -0.07    0.    ] quat=[0.70711 0.      0.70711 0.     ]
   GEOM type=5 size=[0.09   0.0725 0.    ] pos=[-0.2175 -0.07    0.    ] quat=[0.70711 0.      0.70711 0.     ]
   GEOM type=6 size=[0.055 0.07  0.09 ] pos=[0.4695 0.     0.    ] quat=[1. 0. 0. 0.]
   GEOM type=5 size=[0.09  0.055 0.   ] pos=[0.4695 0.07   0.    ] quat=[0.70711 0.      0.70711 0.     ]
   GEOM type=5 size=[0.09  0.055 0.   ] pos=[ 0.4695 -0.07    0.    ] quat=[0.70711 0.      0.70711 0.     ]
   GEOM type=6 size=[0.055 0.07  0.09 ] pos=[-0.4695 -0.      0.    ] quat=[-0.  0.  0.  1.]
   GEOM type=5 size=[0.09  0.055 0.   ] pos=[-0.4695 -0.07    0.    ] quat=[-0.      -0.70711 -0.       0.70711]
   GEOM type=5 size=[0.09  0.055 0.   ] pos=[-0.4695  0.07    0.    ] quat=[-0.      -0.70711 -0.       0.70711]
   GEOM type=6 size=[0.012 0.012 0.005] pos=[0.2488  0.00835 0.05128] quat=[0.70711 0.      0.      0.70711]
   GEOM type=5 size=[0.07 0.06 0.  ] pos=[-0.364   0.      0.1335] quat=[1. 0. 0. 0.]
BODY LF_HIP parent=base pos=[0.2999 0.104  0.    ] quat=[0.25882 0.96593 0.      0.     ] mass=2.78100 ipos=[ 0.05666 -0.01529 -0.0083 ] iquat=[-0.12798  0.70978 -0.13528  0.67936] inertia=[0.00586 0.00492 0.00329]
   JOINT LF_HAA type=3 axis=[1. 0. 0.] pos=[0. 0. 0.] range=[-0.72  0.49] limited=True
   GEOM type=5 size=[0.05 0.07 0.  ] pos=[ 0.0599  -0.01196 -0.00691] quat=[-0.35355 -0.61237  0.61237 -0.35355]
BODY LF_THIGH parent=LF_HIP pos=[ 0.0599  -0.07258 -0.04191] quat=[ 0.18301 -0.68301  0.68301  0.18301] mass=3.07100 ipos=[ 0.03081  0.00005 -0.2457 ] iquat=[ 0.99317 -0.00515 -0.08066  0.0842 ] inertia=[0.03025 0.02989 0.00418]
   JOINT LF_HFE type=3 axis=[1. 0. 0.] pos=[0. 0. 0.] range=[-9.42478  9.42478] limited=True
   GEOM type=5 size=[0.065 0.04  0.   ] pos=[0.04 0.   0.  ] quat=[ 0.5  0.5 -0.5 -0.5]
   GEOM type=6 size=[0.0375  0.03    0.14131] pos=[ 0.03     0.      -0.14131] quat=[ 0.70711  0.       0.      -0.70711]
   GEOM type=5 size=[0.05 0.07 0.  ] pos=[ 0.0303  0.     -0.285 ] quat=[0.70711 0.      0.70711 0.     ]
BODY LF_SHANK parent=LF_THIGH pos=[ 0.1003  0.     -0.285 ] quat=[1. 0. 0. 0.] mass=0.58842 ipos=[ 0.00546 -0.06125 -0.08066] iquat=[ 0.99293 -0.1159  -0.00105 -0.02544] inertia=[0.01016 0.00924 0.00112]
   JOINT LF_KFE type=3 axis=[1. 0. 0.] pos=[0. 0. 0.] range=[-9.42478  9.42478] limited=True
   GEOM type=5 size=[0.06 0.02 0.  ] pos=[0.02 0.   0.  ] quat=[ 0.5  0.5 -0.5 -0.5]
   GEOM type=6 size=[0.0575  0.03375 0.02   ] pos=[ 0.02   -0.0575  0.    ] quat=[ 0.5  0.5 -0.5 -0.5]
   GEOM type=5 size=[0.0175  0.14125 0.     ] pos=[ 0.01305 -0.08795 -0.16898] quat=[ 0.70711  0.       0.      -0.70711]
   GEOM type=2 size=[0.03 0.   0.  ] pos=[ 0.01305 -0.08795 -0.31547] quat=[ 0.70711  0.       0.      -0.70711]
BODY RF_HIP parent=base pos=[ 0.2999 -0.104   0.    ] quat=[ 0.25882 -0.96593  0.       0.     ] mass=2.78100 ipos=[ 0.05676  0.01529 -0.0083 ] iquat=[0.13524 0.67907 0.12798 0.71006] inertia=[0.00586 0.00492 0.00329]
   JOINT RF_HAA type=3 axis=[1. 0. 0.] pos=[0. 0. 0.] range=[-0.49  0.72] limited=True
   GEOM type=5 size=[0.05 0.07 0.  ] pos=[ 0.0599   0.01196 -0.00691] quat=[-0.35355  0.61237  0.61237  0.35355]
BODY RF_THIGH parent=RF_HIP pos=[ 0.0599   0.07258 -0.04191] quat=[ 0.18301  0.68301  0.68301 -0.18301] mass=3.07100 ipos=[ 0.03081  0.00005 -0.2457 ] iquat=[ 0.99277 -0.00513 -0.08067  0.08868] inertia=[0.03025 0.02989 0.00418]
   JOINT RF_HFE type=3 axis=[-1.  0.  0.] pos=[0. 0. 0.] range=[-9.42478  9.42478] limited=True
   GEOM type=5 size=[0.065 0.04  0.   ] pos=[ 0.04 -0.    0.  ] quat=[0.5 0.5 0.5 0.5]
   GEOM type=6 size=[0.0375  0.03    0.14131] pos=[ 0.03    -0.      -0.14131] quat=[0.70711 0.      0.      0.70711]
   GEOM type=5 size=[0.05 0.07 0.  ] pos=[ 0.0303 -0.     -0.285 ] quat=[0.70711 0.      0.70711 0.     ]
BODY RF_SHANK parent=RF_THIGH pos=[ 0.1003 -0.     -0.285 ] quat=[1. 0. 0. 0.] mass=0.58842 ipos=[ 0.00546  0.06125 -0.08066] iquat=[ 0.99293  0.1159  -0.00105  0.02544] inertia=[0.01016 0.00924 0.00112]
   JOINT RF_KFE type=3 axis=[-1.  0.  0.] pos=[0. 0. 0.] range=[-9.42478  9.42478] limited=True
   GEOM type=5 size=[0.06 0.02 0.  ] pos=[ 0.02 -0.    0.  ] quat=[0.5 0.5 0.5 0.5]
   GEOM type=6 size=[0.0575  0.03375 0.02   ] pos=[0.02   0.0575 0.    ] quat=[0.5 0.5 0.5 0.5]
   GEOM type=5 size=[0.0175  0.14125 0.     ] pos=[ 0.01305  0.08795 -0.16898] quat=[0.70711 0.      0.      0.70711]
   GEOM type=2 size=[0.03 0.   0.  ] pos=[ 0.01305  0.08795 -0.31547] quat=[0.70711 0.      0.      0.70711]
BODY LH_HIP parent=base pos=[-0.2999  0.104   0.    ] quat=[-0.       0.       0.96593 -0.25882] mass=2.78100 ipos=[ 0.05676  0.01529 -0.0083 ] iquat=[0.13524 0.67907 0.12798 0.71006] inertia=[0.00586 0.00492 0.00329]
   JOINT LH_HAA type=3 axis=[-1.  0.  0.] pos=[0. 0. 0.] range=[-0.72  0.49] limited=True
   GEOM type=5 size=[0.05 0.07 0.  ] pos=[ 0.0599   0.01196 -0.00691] quat=[-0.35355  0.61237  0.61237  0.35355]
BODY LH_THIGH parent=LH_HIP pos=[ 0.0599   0.07258 -0.04191] quat=[ 0.18301  0.68301  0.68301 -0.18301] mass=3.07100 ipos=[ 0.03081  0.00005 -0.2457 ] iquat=[ 0.99277 -0.00513 -0.08067  0.08868] inertia=[0.03025 0.02989 0.00418]
   JOINT LH_HFE type=3 axis=[1. 0. 0.] pos=[0. 0. 0.] range=[-9.42478  9.42478] limited=True
   GEOM type=5 size=[0.065 0.04  0.   ] pos=[0.04 0.   0.  ] quat=[ 0.5  0.5 -0.5 -0.5]
   GEOM type=6 size=[0.0375  0.03    0.14131] pos=[ 0.03     0.      -0.14131] quat=[ 0.70711  0.       0.      -0.70711]
   GEOM type=5 size=[0.05 0.07 0.  ] pos=[ 0.0303  0.     -0.285 ] quat=[0.70711 0.      0.70711 0.     ]
BODY LH_SHANK parent=LH_THIGH pos=[ 0.1003  0.     -0.285 ] quat=[1. 0. 0. 0.] mass=0.58842 ipos=[ 0.00546  0.06125 -0.08066] iquat=[ 0.99293  0.1159  -0.00105  0.02544] inertia=[0.01016 0.00924 0.00112]
   JOINT LH_KFE type=3 axis=[1. 0. 0.] pos=[0. 0. 0.] range=[-9.42478  9.42478] limited=True
   GEOM type=5 size=[0.06 0.02 0.  ] pos=[0.02 0.   0.  ] quat=[ 0.5  0.5 -0.5 -0.5]
   GEOM type=6 size=[0.0575  0.03375 0.02   ] pos=[0.02   0.0575 0.    ] quat=[ 0.5  0.5 -0.5 -0.5]
   GEOM type=5 size=[0.0175  0.14125 0.     ] pos=[ 0.01305  0.08795 -0.16898] quat=[ 0.70711  0.       0.      -0.70711]
   GEOM type=2 size=[0.03 0.   0.  ] pos=[ 0.01305  0.08795 -0.31547] quat=[ 0.70711  0.       0.      -0.70711]
BODY RH_HIP parent=base pos=[-0.2999 -0.104   0.    ] quat=[-0.      -0.      -0.96593 -0.25882] mass=2.78100 ipos=[ 0.05666 -0.01529 -0.0083 ] iquat=[-0.12798  0.70978 -0.13528  0.67936] inertia=[0.00586 0.00492 0.00329]
   JOINT RH_HAA type=3 axis=[-1.  0.  0.] pos=[0. 0. 0.] range=[-0.49  0.72] limited=True
   GEOM type=5 size=[0.05 0.07 0.  ] pos=[ 0.0599  -0.01196 -0.00691] quat=[ 0.35355  0.61237 -0.61237  0.35355]
BODY RH_THIGH parent=RH_HIP pos=[ 0.0599  -0.07258 -0.04191] quat=[-0.18301  0.68301 -0.68301 -0.18301] mass=3.07100 ipos=[ 0.03081  0.00005 -0.2457 ] iquat=[ 0.99317 -0.00515 -0.08066  0.0842 ] inertia=[0.03025 0.02989 0.00418]
   JOINT RH_HFE type=3 axis=[-1.  0.  0.] pos=[0. 0. 0.] range=[-9.42478  9.42478] limited=True
   GEOM type=5 size=[0.065 0.04  0.   ] pos=[ 0.04 -0.    0.  ] quat=[0.5 0.5 0.5 0.5]
   GEOM type=6 size=[0.0375  0.03    0.14131] pos=[ 0.03    -0.      -0.14131] quat=[0.70711 0.      0.      0.70711]
   GEOM type=5 size=[0.05 0.07 0.  ] pos=[ 0.0303 -0.     -0.285 ] quat=[0.70711 0.      0.70711 0.     ]
BODY RH_SHANK parent=RH_THIGH pos=[ 0.1003 -0.     -0.285 ] quat=[1. 0. 0. 0.] mass=0.58842 ipos=[ 0.00546 -0.06125 -0.08066] iquat=[ 0.99293 -0.1159  -0.00105 -0.02544] inertia=[0.01016 0.00924 0.00112]
   JOINT RH_KFE type=3 axis=[-1.  0.  0.] pos=[0. 0. 0.] range=[-9.42478  9.42478] limited=True
   GEOM type=5 size=[0.06 0.02 0.  ] pos=[ 0.02 -0.    0.  ] quat=[0.5 0.5 0.5 0.5]
   GEOM type=6 size=[0.0575  0.03375 0.02   ] pos=[ 0.02   -0.0575  0.    ] quat=[0.5 0.5 0.5 0.5]
   GEOM type=5 size=[0.0175  0.14125 0.     ] pos=[ 0.01305 -0.08795 -0.16898] quat=[0.70711 0.      0.      0.70711]
   GEOM type=2 size=[0.03 0.   0.  ] pos=[ 0.01305 -0.08795 -0.31547] quat=[0.70711 0.      0.      0.70711]
"""


# ----------------------------------------------------------------------------- helpers


def _vec(text: str) -> np.ndarray:
    return np.array([float(x) for x in text.split()])


def parse_listing(text: str = REFERENCE_LISTING) -> dict[str, dict]:
    """Bodies of the listing by name, each with its numbers, its joints and its geoms in order."""
    bodies: dict[str, dict] = {}
    current = None
    for line in text.strip().splitlines():
        if m := re.match(
            r"BODY (\S+) parent=(\S+) pos=\[(.*?)\] quat=\[(.*?)\] mass=(\S+) "
            r"ipos=\[(.*?)\] iquat=\[(.*?)\] inertia=\[(.*?)\]",
            line,
        ):
            name, parent, pos, quat, mass, ipos, iquat, inertia = m.groups()
            current = bodies[name] = dict(
                parent=parent,
                pos=_vec(pos),
                quat=_vec(quat),
                mass=float(mass),
                ipos=_vec(ipos),
                iquat=_vec(iquat),
                inertia=_vec(inertia),
                joints=[],
                geoms=[],
            )
        elif m := re.match(
            r"\s+JOINT (\S+) type=(\d) axis=\[(.*?)\] pos=\[(.*?)\] range=\[(.*?)\] "
            r"limited=(\w+)",
            line,
        ):
            name, jtype, axis, _, jrange, limited = m.groups()
            current["joints"].append(
                dict(name=name, type=int(jtype), axis=_vec(axis), range=_vec(jrange), limited=limited == "True")
            )
        elif m := re.match(r"\s+GEOM type=(\d) size=\[(.*?)\] pos=\[(.*?)\] quat=\[(.*?)\]", line):
            gtype, size, pos, quat = m.groups()
            current["geoms"].append(dict(type=int(gtype), size=_vec(size), pos=_vec(pos), quat=_vec(quat)))
    return bodies


REFERENCE = parse_listing()


def expand(**mappings: str) -> str:
    """The URDF text of the description for the given xacro arguments."""
    return xacro.process_file(str(XACRO_FILE), mappings=dict(mappings)).toxml()


MUJOCO_IMPORT = (
    '<mujoco><compiler fusestatic="true" discardvisual="true" inertiafromgeom="false" '
    'balanceinertia="false" strippath="false"/></mujoco>'
    '<link name="footforge_root"/>'
    '<joint name="floating_base" type="floating">'
    '<parent link="footforge_root"/><child link="base"/></joint>'
)


def mujoco_model(urdf: str) -> mujoco.MjModel:
    """Import a URDF into MuJoCo as the listing was made: static bodies fused, no inertia from
    geoms, visuals dropped, and a free joint on the base (a floating joint from a dummy root link,
    which fusestatic merges into the world)."""
    start = re.search(r"<robot\b[^>]*>", urdf)
    return mujoco.MjModel.from_xml_string(urdf[: start.end()] + MUJOCO_IMPORT + urdf[start.end() :])


def quat_to_matrix(quat: np.ndarray) -> np.ndarray:
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=float) / np.linalg.norm(quat))
    return out.reshape(3, 3)


def inertia_tensor(iquat: np.ndarray, moments: np.ndarray) -> np.ndarray:
    rot = quat_to_matrix(iquat)
    return rot @ np.diag(moments) @ rot.T


def quat_distance(q1: np.ndarray, q2: np.ndarray) -> float:
    """Distance between two unit quaternions, blind to the sign (q and -q are the same rotation)."""
    return float(min(np.abs(q1 - q2).max(), np.abs(q1 + q2).max()))


def body_geoms(model: mujoco.MjModel, body_id: int) -> list[int]:
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] == body_id]


@pytest.fixture(scope="module")
def urdf_ball() -> str:
    return expand(foot="ball")


@pytest.fixture(scope="module")
def urdf_none() -> str:
    return expand(foot="none")


@pytest.fixture(scope="module")
def model_ball(urdf_ball: str) -> mujoco.MjModel:
    return mujoco_model(urdf_ball)


@pytest.fixture(scope="module")
def model_none(urdf_none: str) -> mujoco.MjModel:
    return mujoco_model(urdf_none)


# ----------------------------------------------------------------------------- MuJoCo vs listing


def test_body_tree_and_totals(model_ball: mujoco.MjModel) -> None:
    assert model_ball.nbody == 14 and model_ball.njnt == 13
    names = [model_ball.body(b).name for b in range(1, model_ball.nbody)]
    assert names == list(REFERENCE)
    assert model_ball.body_mass.sum() == pytest.approx(TOTAL_MASS, abs=1e-4)
    assert sum(b["mass"] for b in REFERENCE.values()) == pytest.approx(TOTAL_MASS, abs=1e-9)
    free = model_ball.joint("floating_base")
    assert free.type[0] == mujoco.mjtJoint.mjJNT_FREE and model_ball.body(free.bodyid[0]).name == "base"


@pytest.mark.parametrize("body", list(REFERENCE))
def test_body_frames_and_inertials(model_ball: mujoco.MjModel, body: str) -> None:
    ref = REFERENCE[body]
    b = model_ball.body(body)
    assert model_ball.body(b.parentid[0]).name == ref["parent"]
    np.testing.assert_allclose(b.pos, ref["pos"], atol=1e-5)
    assert quat_distance(b.quat, ref["quat"]) < 1e-4
    assert b.mass[0] == pytest.approx(ref["mass"], abs=1e-6)
    np.testing.assert_allclose(b.ipos, ref["ipos"], atol=1e-5)
    np.testing.assert_allclose(np.sort(b.inertia), np.sort(ref["inertia"]), rtol=1e-3)
    # Principal axes: their order and signs are ambiguous, so compare the whole tensor in the body frame.
    tensor = inertia_tensor(b.iquat, b.inertia)
    expected = inertia_tensor(ref["iquat"], ref["inertia"])
    np.testing.assert_allclose(tensor, expected, atol=1e-3 * ref["inertia"].max())
    # Physically consistent: positive moments obeying the triangle inequality.
    moments = np.sort(b.inertia)
    assert moments[0] > 0 and moments[0] + moments[1] >= moments[2]


@pytest.mark.parametrize("body", list(REFERENCE))
def test_joints(model_ball: mujoco.MjModel, body: str) -> None:
    b = model_ball.body(body)
    joints = [j for j in range(model_ball.njnt) if model_ball.jnt_bodyid[j] == b.id]
    assert [model_ball.joint(j).name for j in joints] == [j["name"] for j in REFERENCE[body]["joints"]]
    for j, ref in zip(joints, REFERENCE[body]["joints"]):
        assert model_ball.jnt_type[j] == ref["type"]
        np.testing.assert_allclose(model_ball.jnt_pos[j], 0.0, atol=1e-12)
        if ref["type"] == mujoco.mjtJoint.mjJNT_HINGE:
            np.testing.assert_allclose(model_ball.jnt_axis[j], ref["axis"], atol=1e-9)
            np.testing.assert_allclose(model_ball.jnt_range[j], ref["range"], atol=1e-5)
            assert bool(model_ball.jnt_limited[j]) == ref["limited"]


@pytest.mark.parametrize("body", list(REFERENCE))
def test_collision_geoms(model_ball: mujoco.MjModel, body: str) -> None:
    geoms = body_geoms(model_ball, model_ball.body(body).id)
    refs = REFERENCE[body]["geoms"]
    assert len(geoms) == len(refs)
    for g, ref in zip(geoms, refs):
        assert model_ball.geom_type[g] == ref["type"]
        np.testing.assert_allclose(model_ball.geom_size[g], ref["size"], atol=1e-5)
        np.testing.assert_allclose(model_ball.geom_pos[g], ref["pos"], atol=1e-5)
        assert quat_distance(model_ball.geom_quat[g], ref["quat"]) < 1e-4


def test_steps_without_warnings(model_ball: mujoco.MjModel) -> None:
    data = mujoco.MjData(model_ball)
    for _ in range(250):
        mujoco.mj_step(model_ball, data)
    assert np.all(np.isfinite(data.qpos))
    assert all(w.number == 0 for w in data.warning)


# ----------------------------------------------------------------------------- foot argument


def test_foot_none_has_no_ball_and_same_mass(model_ball: mujoco.MjModel, model_none: mujoco.MjModel) -> None:
    assert mujoco.mjtGeom.mjGEOM_SPHERE not in set(model_none.geom_type)
    assert model_none.body_mass.sum() == pytest.approx(TOTAL_MASS, abs=1e-4)
    assert model_none.nbody == model_ball.nbody
    for leg in LEGS:
        ball_geoms = body_geoms(model_ball, model_ball.body(f"{leg}_SHANK").id)
        none_geoms = body_geoms(model_none, model_none.body(f"{leg}_SHANK").id)
        assert len(none_geoms) == len(ball_geoms) - 1
        # the foot adapter tube stays
        np.testing.assert_allclose(
            model_none.geom_size[none_geoms][:, :2], model_ball.geom_size[ball_geoms[:-1]][:, :2], atol=1e-12
        )
    np.testing.assert_allclose(model_none.body_inertia, model_ball.body_inertia, atol=1e-12)


def _listing_world_pose(body: str) -> tuple[np.ndarray, np.ndarray]:
    """Pose of a listing body at q = 0 with the base at the origin, composed from the listing."""
    ref = REFERENCE[body]
    if ref["parent"] == "world":
        return ref["pos"], quat_to_matrix(ref["quat"])
    pos, rot = _listing_world_pose(ref["parent"])
    return pos + rot @ ref["pos"], rot @ quat_to_matrix(ref["quat"])


def _pinocchio_frames(urdf: str) -> tuple[pin.Model, pin.Data]:
    model = pin.buildModelFromXML(urdf)
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    return model, data


@pytest.mark.parametrize("foot", ["ball", "none"])
def test_foot_mount_frame(foot: str) -> None:
    model, data = _pinocchio_frames(expand(foot=foot))
    for leg in LEGS:
        assert model.existFrame(f"{leg}_foot_mount")
        mount = data.oMf[model.getFrameId(f"{leg}_foot_mount")]
        foot_frame = data.oMf[model.getFrameId(f"{leg}_FOOT")]
        expected = foot_frame * pin.SE3(np.eye(3), np.array([0.0, 0.0, BALL_Z]))
        assert mount.isApprox(expected, 1e-12)
        # At q = 0 every FOOT and mount frame is parallel to the base.
        np.testing.assert_allclose(mount.rotation, np.eye(3), atol=1e-12)
        # The mount sits at the ball centre of the published listing (last geom of the SHANK).
        pos, rot = _listing_world_pose(f"{leg}_SHANK")
        ball_centre = pos + rot @ REFERENCE[f"{leg}_SHANK"]["geoms"][-1]["pos"]
        np.testing.assert_allclose(mount.translation, ball_centre, atol=2e-5)


def test_foot_mount_pose_is_an_argument() -> None:
    model, data = _pinocchio_frames(
        expand(foot="none", foot_mount_xyz="0.01 0 -0.03", foot_mount_rpy="0 0 1.5707963267948966")
    )
    for leg in LEGS:
        relative = data.oMf[model.getFrameId(f"{leg}_FOOT")].actInv(data.oMf[model.getFrameId(f"{leg}_foot_mount")])
        np.testing.assert_allclose(relative.translation, [0.01, 0.0, -0.03], atol=1e-12)
        np.testing.assert_allclose(relative.rotation, pin.rpy.rpyToMatrix(0, 0, np.pi / 2), atol=1e-12)


def test_invalid_foot_raises() -> None:
    with pytest.raises(xacro.XacroException, match="invalid foot"):
        expand(foot="flat")


def test_softfoot_q_is_included_only_when_asked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The real softfoot_q package is written elsewhere; a stub with the same macro signature checks
    # the wiring here. $(find) must not be evaluated for the other foot values.
    def find_nothing(pkg: str) -> str:
        raise AssertionError(f"$(find {pkg}) evaluated")

    monkeypatch.setattr(xacro.substitution_args, "_eval_find", find_nothing)
    expand(foot="ball")
    expand(foot="none")

    stub = tmp_path / "softfoot_q" / "urdf" / "softfoot_q.xacro"
    stub.parent.mkdir(parents=True)
    stub.write_text(
        '<robot xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:macro name="softfoot_q" params="prefix parent">'
        '<link name="${prefix}ankle"><inertial><mass value="0.415"/>'
        '<inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>'
        '<joint name="${prefix}mount" type="fixed"><parent link="${parent}"/>'
        '<child link="${prefix}ankle"/></joint>'
        "</xacro:macro></robot>"
    )
    monkeypatch.setattr(xacro.substitution_args, "_eval_find", lambda pkg: str(tmp_path / pkg))
    urdf = expand(foot="softfoot_q")
    root = etree.fromstring(urdf.encode())
    for leg in LEGS:
        joint = root.find(f"joint[@name='{leg}_foot_mount']")
        assert joint.find("parent").get("link") == f"{leg}_foot_mount"
        assert joint.find("child").get("link") == f"{leg}_foot_ankle"
    assert not root.findall(".//sphere")
    assert mujoco_model(urdf).body_mass.sum() == pytest.approx(TOTAL_MASS + 4 * 0.415, abs=1e-4)


# ----------------------------------------------------------------------------- URDF structure


def test_urdf_structure(urdf_ball: str) -> None:
    root = etree.fromstring(urdf_ball.encode())
    assert root.get("name") == "anymal_c"
    links = {link.get("name"): link for link in root.findall("link")}
    children = {j.find("child").get("link") for j in root.findall("joint")}
    assert set(links) - children == {"base"}  # base is the root
    assert "imu_link" in links
    for name, link in links.items():
        if name in MOVING_LINKS:
            assert link.find("inertial") is not None
            collisions, visuals = link.findall("collision"), link.findall("visual")
            assert collisions and len(collisions) == len(visuals)
            for c, v in zip(collisions, visuals):  # every collision has an identical visual
                assert etree.tostring(c.find("origin")) == etree.tostring(v.find("origin"))
                assert etree.tostring(c.find("geometry")) == etree.tostring(v.find("geometry"))
                assert c.find("geometry")[0].tag in ("box", "cylinder", "sphere")
        else:  # fixed frames are pure frames
            assert len(link) == 0, f"{name} should have no inertial and no geometry"
    revolute = [j for j in root.findall("joint") if j.get("type") == "revolute"]
    assert sorted(j.get("name") for j in revolute) == sorted(
        f"{leg}_{dof}" for leg in LEGS for dof in ("HAA", "HFE", "KFE")
    )
    for joint in revolute:
        limit = joint.find("limit")
        assert float(limit.get("effort")) == 80.0 and float(limit.get("velocity")) == 7.5


def test_pinocchio_agrees(urdf_ball: str, model_ball: mujoco.MjModel) -> None:
    model = pin.buildModelFromXML(urdf_ball, pin.JointModelFreeFlyer())
    assert model.nq == 19 and model.nv == 18
    assert pin.computeTotalMass(model) == pytest.approx(TOTAL_MASS, abs=1e-9)
    np.testing.assert_allclose(model.effortLimit[6:], 80.0)
    np.testing.assert_allclose(model.velocityLimit[6:], 7.5)
    # Joint-space mass matrix at a random pose equals MuJoCo's (same joints, same order by name).
    rng = np.random.default_rng(0)
    names = [model.names[i] for i in range(2, model.njoints)]
    q_hinge = {name: rng.uniform(-0.4, 0.4) for name in names}
    q_pin = pin.neutral(model)
    for i, name in enumerate(names, start=2):
        q_pin[model.joints[i].idx_q] = q_hinge[name]
    mass_pin = pin.crba(model, model.createData(), q_pin)
    mass_pin = np.triu(mass_pin) + np.triu(mass_pin, 1).T
    data = mujoco.MjData(model_ball)
    for name, value in q_hinge.items():
        data.qpos[model_ball.joint(name).qposadr[0]] = value
    mujoco.mj_forward(model_ball, data)
    mass_mj = np.zeros((model_ball.nv, model_ball.nv))
    mujoco.mj_fullM(model_ball, data, mass_mj)
    # Map pinocchio's dof order onto MuJoCo's (both put the free joint first). With the base at the
    # origin and unrotated, pinocchio's local free-flyer velocity and MuJoCo's (linear in world,
    # angular in body) coincide, so the whole 18x18 matrix is comparable.
    order = list(range(6)) + [model_ball.joint(name).dofadr[0] for name in names]
    np.testing.assert_allclose(mass_pin, mass_mj[np.ix_(order, order)], atol=1e-9)


def test_inertials_reproducible_from_listing(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "dont_write_bytecode", True)  # no __pycache__ inside descriptions/
    spec = importlib.util.spec_from_file_location("derive_inertials", DESCRIPTION / "derive_inertials.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.check_xacro(XACRO_FILE) == []
    for body, data in module.FUSED_INERTIALS.items():  # the script's data is the listing's
        assert data["mass"] == REFERENCE[body]["mass"]
        np.testing.assert_array_equal(data["iquat"], REFERENCE[body]["iquat"])
        np.testing.assert_array_equal(data["inertia"], REFERENCE[body]["inertia"])
        np.testing.assert_array_equal(data["ipos"], REFERENCE[body]["ipos"])
