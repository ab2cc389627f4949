"""The derived feet's collision geometry (params.FootContact, the parameter file's `collision`):
the sole as a box or as spheres or capsules on the box's bottom face, with or without the parts
above the sole colliding."""

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

from footforge.errors import InputError
from footforge.inputs.params import FootContact, default_params_path, load_params
from footforge.mjcf.foot import collision_points, sole_primitives

SHAPES = {
    "box": {"sole": "box", "upper_collisions": True},
    "box_sole_only": {"sole": "box", "upper_collisions": False},
    "spheres": {"sole": "spheres", "grid": [2, 2], "radius_m": 0.01, "upper_collisions": False},
    "capsules": {"sole": "capsules", "grid": [1, 2], "radius_m": 0.01, "upper_collisions": False},
}


SOLE_LIFT_M = 0.015
"""One sole lift for every geometry compared here. The shipped AFF lift (22.7 mm since its
2026-11-25 recalibration) raises the sole above the ankle, arch and roll boxes (about 16 mm up),
which build refuses where those collide too (test_validate's lift test); 15 mm fits every geometry."""


def _params_with(tmp_path: Path, contact: dict, variants=("aff", "aof")) -> Path:
    data = yaml.safe_load(default_params_path().read_text())
    for v in variants:
        data[v]["collision"] = contact
        data[v]["sole_lift_m"] = SOLE_LIFT_M
    path = tmp_path / f"params_{len(list(tmp_path.glob('params_*.yaml')))}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def builds(tmp_path_factory, coacd_cache):
    """AFF and AOF rigs and robots with each sole shape: {(variant, shape): out_dir}."""
    from footforge.build import BuildOptions, build

    root = tmp_path_factory.mktemp("contact")
    out = {}
    for shape, contact in SHAPES.items():
        params = _params_with(root, contact)
        for variant in ("aff", "aof"):
            out[variant, shape] = root / f"{variant}_{shape}"
            build(
                BuildOptions(
                    variant=variant,
                    out_dir=out[variant, shape],
                    params=params,
                    cache_dir=coacd_cache,
                    formats=("mjcf",),
                )
            )
    return out


@pytest.mark.parametrize("shape", ["spheres", "capsules"])
def test_primitives_lie_on_the_box_bottom_face(shape):
    center, half = np.array([0.01, -0.002, -0.03]), np.array([0.06, 0.027, 0.018])
    contact = FootContact(**{k: tuple(v) if k == "grid" else v for k, v in SHAPES[shape].items()})
    geoms = sole_primitives(center, half, contact)
    assert len(geoms) == contact.grid[0] * contact.grid[1]
    r = contact.radius_m
    # Each primitive's extreme points along x, y and down, from its own geometry.
    pts = []
    for g in geoms:
        ends = [g["pos"]] if shape == "spheres" else [g["fromto"][:3], g["fromto"][3:]]
        pts += [np.asarray(e, float) + d for e in ends for d in r * np.vstack([np.eye(3), -np.eye(3)])]
    pts = np.array(pts)
    bottom = center[2] - half[2]
    assert pts[:, 2].min() == pytest.approx(bottom, abs=1e-12)
    lowest = [
        min(
            np.asarray(e, float)[2] - r
            for e in ([g["pos"]] if shape == "spheres" else [g["fromto"][:3], g["fromto"][3:]])
        )
        for g in geoms
    ]
    np.testing.assert_allclose(lowest, bottom, atol=1e-12)  # every one touches a flat floor
    np.testing.assert_allclose(pts[:, :2].min(0), center[:2] - half[:2], atol=1e-12)  # reach the edges
    np.testing.assert_allclose(pts[:, :2].max(0), center[:2] + half[:2], atol=1e-12)


@pytest.mark.parametrize("shape", ["box_sole_only", "spheres", "capsules"])
def test_only_the_sole_collides_and_mass_is_unchanged(builds, shape):
    for variant in ("aff", "aof"):
        box = mujoco.MjModel.from_xml_path(str(builds[variant, "box"] / "robot.xml"))
        new = mujoco.MjModel.from_xml_path(str(builds[variant, shape] / "robot.xml"))
        np.testing.assert_array_equal(new.body_mass, box.body_mass)
        np.testing.assert_array_equal(new.body_inertia, box.body_inertia)
        colliding = [new.geom(g).name for g in range(new.ngeom) if new.geom_contype[g] or new.geom_conaffinity[g]]
        foot = [n for n in colliding if "_foot/" in n]
        expected_type = {
            "box_sole_only": mujoco.mjtGeom.mjGEOM_BOX,
            "spheres": mujoco.mjtGeom.mjGEOM_SPHERE,
            "capsules": mujoco.mjtGeom.mjGEOM_CAPSULE,
        }[shape]
        assert foot and all(n.split("/")[1].startswith("sole") for n in foot), foot
        assert all(new.geom_type[new.geom(n).id] == expected_type for n in foot)
        per_plate = {"box_sole_only": 1, "spheres": 4, "capsules": 2}[shape]
        assert len(foot) == 4 * per_plate * (1 if variant == "aff" else 2)
        report = json.loads((builds[variant, shape] / "build_report.json").read_text())
        assert report["foot"]["sole_clearance_m"] is None  # nothing else collides
        assert report["foot"]["contact"]["sole"] == SHAPES[shape]["sole"]
        assert report["foot"]["contact"]["upper_collisions"] is False

        # The leg's own colliders (shanks, thighs, base) are those of the box build.
        def legs(m):
            return sorted(
                m.geom(g).name
                for g in range(m.ngeom)
                if (m.geom_contype[g] or m.geom_conaffinity[g]) and "_foot/" not in m.geom(g).name
            )

        assert legs(new) == legs(box)


def _settle(model: mujoco.MjModel, seconds: float = 1.5) -> tuple[float, float]:
    """The rig dropped 2 cm with its payload onto flat ground: (slider height m, floor normal force
    / weight) at the end."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("reference").id)
    slider = model.jnt_qposadr[model.joint("slider").id]
    data.qpos[slider] += 0.02
    for _ in range(int(round(seconds / model.opt.timestep))):
        mujoco.mj_step(model, data)
    force, normal = np.zeros(6), 0.0
    for i in range(data.ncon):
        mujoco.mj_contactForce(model, data, i, force)
        normal += force[0] * abs(data.contact[i].frame[2])
    weight = sum(model.body_mass[1:]) * -model.opt.gravity[2]
    return float(data.qpos[slider]), normal / weight


@pytest.mark.parametrize("variant", ["aff", "aof"])
@pytest.mark.parametrize("shape", ["spheres", "capsules"])
def test_sole_stands_where_the_box_stands(builds, variant, shape):
    """On flat ground the primitives' lowest points are the box's bottom face, so the loaded foot
    settles at the box's height, carrying the whole weight."""
    box_height, box_load = _settle(mujoco.MjModel.from_xml_path(str(builds[variant, "box"] / "foot_rig.xml")))
    height, load = _settle(mujoco.MjModel.from_xml_path(str(builds[variant, shape] / "foot_rig.xml")))
    assert load == pytest.approx(1.0, rel=0.02) and box_load == pytest.approx(1.0, rel=0.02)
    # Contacts penetrate by their load's share: 4-8 contacts instead of the box's 4 per plate.
    assert abs(height - box_height) < 0.5e-3, (height, box_height)


def test_shipped_parameters_read(tmp_path):
    params = load_params()
    for variant in ("aff", "aof"):  # the sole box alone (benchmarks/log/2026-11-21_to_26.md, 2026-11-25)
        assert params.foot_contact[variant] == FootContact(sole="box", upper_collisions=False)
    # A file without `collision` keeps the box soles, everything colliding (files written before it).
    data = yaml.safe_load(default_params_path().read_text())
    for v in ("aff", "aof"):
        data[v].pop("collision")
    path = tmp_path / "old.yaml"
    path.write_text(yaml.safe_dump(data))
    old = FootContact(sole="box", grid=(2, 2), radius_m=0.01, upper_collisions=True)
    assert load_params(path).foot_contact == {"aff": old, "aof": old}


@pytest.mark.parametrize(
    "contact, key, message",
    [
        ({"sole": "cubes"}, "aff.collision.sole", "unknown sole contact 'cubes'"),
        ({"sole": "spheres", "grid": [0, 2]}, "aff.collision.grid", "bad grid"),
        ({"sole": "spheres", "grid": [2.5, 2]}, "aff.collision.grid", "bad grid"),
        ({"sole": "spheres", "grid": "2x2"}, "aff.collision.grid", "expected a list of 2 numbers"),
        ({"sole": "spheres", "radius_m": -1}, "aff.collision.radius_m", "below"),
        ({"sole": "spheres", "upper_collisions": "no"}, "aff.collision.upper_collisions", "true or false"),
        ({"sole": "spheres", "size": 3}, "aff.collision", "unknown keys ['size']"),
        ({"sole": "box", "grid": [2, 2]}, "aff.collision.grid", "a box sole has no grid or radius"),
        ("box", "aff.collision", "expected a mapping"),
    ],
)
def test_bad_contact_parameters_name_the_key(tmp_path, contact, key, message):
    with pytest.raises(InputError) as e:
        load_params(_params_with(tmp_path, contact, variants=("aff",)))
    text = str(e.value)
    assert message in text and key in text, text


def test_radius_wider_than_the_plate_is_refused(tmp_path, coacd_cache, capsys):
    from footforge.cli.main import main

    path = _params_with(tmp_path, {"sole": "spheres", "radius_m": 0.04}, variants=("aof",))
    out = tmp_path / "out"
    code = main(
        [
            "build",
            "--variant",
            "aof",
            "--format",
            "mjcf",
            "--params",
            str(path),
            "--out",
            str(out),
            "--cache-dir",
            str(coacd_cache),
        ]
    )
    captured = capsys.readouterr()
    text = " ".join((captured.out + captured.err).split())  # rich wraps long lines
    assert code == 2 and "aof.collision.radius_m" in text and "Traceback" not in text
    assert not out.exists()


@pytest.mark.parametrize("shape", ["spheres", "capsules"])
def test_a_calibration_trial_s_sole_lift_moves_the_contacts(builds, shape):
    """A calibration trial lowers the sole (Case.patch's sole_lift_delta_m) of a rig whose sole
    body holds several colliding geoms: 0.5 mm above the floor it touches nothing, lowered by 1 mm
    it touches with every primitive (moved in the compiled model, the body's stale bounding box
    hid them all)."""
    from footforge.validate.simulate import compile_case

    folder = builds["aff", shape]
    xml = (folder / "foot_rig.xml").read_text()
    assets = {f.name: f.read_bytes() for f in (folder / "assets").iterdir()}
    model = compile_case(xml, assets, None)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("reference").id)
    mujoco.mj_kinematics(model, data)
    soles = [model.body(b).name for b in range(model.nbody) if model.body(b).name.startswith("foot/sole")]
    lowest = collision_points(model, data, soles)[:, 2].min()
    slider = model.jnt_qposadr[model.joint("slider").id]
    touching = {}
    for delta in (0.0, -0.001):
        model = compile_case(xml, assets, {"sole_lift_delta_m": delta})
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, model.key("reference").id)
        data.qpos[slider] -= lowest - 0.0005  # the sole's bottom 0.5 mm above the floor
        mujoco.mj_forward(model, data)
        touching[delta] = data.ncon
    # AFF: 4 spheres, one contact each, or 2 capsules, two each.
    assert touching == {0.0: 0, -0.001: 4}
