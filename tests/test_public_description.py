"""The public SoftFoot-Q description as its owners ship it (issue 14): a ROS package whose robot
files hang the foot from a `world` link, with repeated <origin> elements, an impossible ankle
inertia and large meshes. One command must build it: the shipped public sidecar is found, the
rig above the foot's root link is dropped, `--repair` fixes the defects, and every message names
the flag or sidecar key to change.

The fixture tests/fixtures/public_softfoot/ has the package's layout and names, with footforge's
own xacro text and small box meshes generated here (the package's files are not copied)."""

import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

from footforge.cli.main import main
from footforge.errors import InputError
from footforge.inputs.description import load_description
from footforge.inputs.foot_root import select_foot_root
from footforge.inputs.urdf_lint import check_urdf
from footforge.models.collision import DecompositionConfig, decompose
from footforge.models.mesh_simplify import simplify_to_budget

from conftest import REPO

FIXTURE = Path(__file__).parent / "fixtures" / "public_softfoot"
PUBLIC_SIDECAR = REPO / "descriptions" / "softfoot_q" / "public_sidecar.yaml"
BOX_MM = {
    "ankle": (40, 40, 30),
    "front_arch_front": (70, 28, 20),
    "front_arch_back": (70, 28, 20),
    "roll_link_v04": (15, 50, 25),
    "inner_chain": (11, 12, 12),
    "outer_chain": (17, 21, 12),
}
"""Collision boxes of the fixture's parts, mm (the package's meshes are in mm, scaled by .001)."""


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out + out.err


@pytest.fixture
def public_pkg(tmp_path):
    """The fixture package in a fresh folder, with its collision meshes generated."""
    root = tmp_path / "ws"
    shutil.copytree(FIXTURE, root)
    meshes = root / "softfoot_thing_description" / "meshes" / "collision"
    meshes.mkdir(parents=True)
    for name, size in BOX_MM.items():
        trimesh.creation.box(extents=size).export(meshes / f"{name}.stl")
    return root


def robot_file(pkg: Path, name: str) -> Path:
    return pkg / "softfoot_thing_description" / "robot" / name


def sidecar_copy(tmp_path, **changes) -> Path:
    data = yaml.safe_load(PUBLIC_SIDECAR.read_text())
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    path = tmp_path / "edited.sidecar.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_public_rig_builds_in_one_command(capsys, tmp_path, public_pkg):
    """world -> floating leg -> foot: the shipped sidecar is picked up, the rig dropped, the
    repeated origins and the ankle inertia repaired (before: 'sidecar file not found')."""
    out = tmp_path / "out"
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aof",
        "--foot-only",
        "--format",
        "mjcf",
        "--description",
        robot_file(public_pkg, "floating_softfoot.urdf.xacro"),
        "--package-path",
        public_pkg,
        "--repair",
        "--out",
        out,
        "--cache-dir",
        tmp_path / "c",
    )
    assert code == 0, text
    report = yaml.safe_load((out / "build_report.json").read_text())
    assert report["inputs"]["sidecar"]["path"] == str(PUBLIC_SIDECAR.resolve())
    repairs = "\n".join(report["repairs"])
    assert "root link 'softfoot_ankle_base_link'" in repairs and "world" in repairs and "leg_link" in repairs
    assert "repeated <origin>" in repairs and "softfoot_ankle_link" in repairs
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(out / "foot.xml"))
    assert model.body(1).name == "softfoot_ankle_base_link"


def test_fixed_world_root_is_dropped_without_root_link(capsys, tmp_path, public_pkg):
    """A foot fixed to `world` and no root_link in the sidecar: `world` and its fixed joint are
    dropped (before: a dm_control traceback on the body named 'world', after CoACD)."""
    out = tmp_path / "out"
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aof",
        "--foot-only",
        "--format",
        "mjcf",
        "--description",
        robot_file(public_pkg, "fixed_softfoot.urdf.xacro"),
        "--sidecar",
        sidecar_copy(tmp_path, root_link=None),
        "--package-path",
        public_pkg,
        "--repair",
        "--out",
        out,
        "--cache-dir",
        tmp_path / "c",
    )
    assert code == 0, text
    assert "Traceback" not in text
    report = yaml.safe_load((out / "build_report.json").read_text())
    assert any("dropped 1 link(s)" in r and "world" in r for r in report["repairs"])


def test_moving_rig_without_root_link_asks_for_it(tmp_path, public_pkg):
    desc = load_description(robot_file(public_pkg, "floating_softfoot.urdf.xacro"), package_paths=[public_pkg])
    with pytest.raises(InputError) as e:
        select_foot_root(desc, None, sidecar_path=tmp_path / "s.yaml")
    assert "root_link" in e.value.fix and "s.yaml" in e.value.fix and "floating" in e.value.message


def test_root_link_typo_names_the_sidecar_key(capsys, tmp_path, public_pkg):
    """root_link was parsed and ignored: a wrong one went unnoticed."""
    sidecar = sidecar_copy(tmp_path, root_link="softfoot_ankle_bse_link")
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aof",
        "--foot-only",
        "--repair",
        "--description",
        robot_file(public_pkg, "floating_softfoot.urdf.xacro"),
        "--sidecar",
        sidecar,
        "--package-path",
        public_pkg,
        "--out",
        tmp_path / "out",
        "--cache-dir",
        tmp_path / "c",
    )
    assert code == 2, text
    assert "root_link" in text and str(sidecar) in text and "softfoot_ankle_base_link" in text
    assert not (tmp_path / "c").exists(), "checked before CoACD"


def test_sidecar_name_typo_blames_the_sidecar(capsys, tmp_path, public_pkg):
    """A misspelt joint or link in the sidecar: the message names the sidecar file, the key and
    the closest names (before: 'no link named ... in the description', the description's path)."""
    data = yaml.safe_load(PUBLIC_SIDECAR.read_text())
    data["arch_joints"][0] = "softfoot_front_arc_joint"
    data["closures"][2]["link"] = "softfoot_left_chain_9"
    sidecar = tmp_path / "typo.sidecar.yaml"
    sidecar.write_text(yaml.safe_dump(data))
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aof",
        "--foot-only",
        "--repair",
        "--description",
        robot_file(public_pkg, "floating_softfoot.urdf.xacro"),
        "--sidecar",
        sidecar,
        "--package-path",
        public_pkg,
        "--out",
        tmp_path / "out",
        "--cache-dir",
        tmp_path / "c",
    )
    assert code == 2, text
    assert str(sidecar) in text
    assert "arch_joints[0]" in text and "softfoot_front_arch_joint" in text
    assert "closures[2].link" in text and "softfoot_left_chain_9_link" in text
    assert "check the name against the URDF" not in text
    assert not (tmp_path / "c").exists(), "checked before CoACD"


def test_repair_fixes_name_the_flag(public_pkg):
    """The check's fixes told users about `repair_urdf`, an internal function."""
    desc = load_description(robot_file(public_pkg, "floating_softfoot.urdf.xacro"), package_paths=[public_pkg])
    findings = [f for f in check_urdf(desc.root(), resolve_uri=desc.resolve_uri) if f.repairable]
    codes = {f.code for f in findings}
    assert {"repeated_element", "triangle_inequality"} <= codes
    for f in findings:
        assert "repair_urdf" not in f.fix, f.fix
    assert any("--repair" in f.fix for f in findings)


def test_coacd_timeout_names_the_flag(tmp_path):
    """The timeout message said 'simplify the mesh' and never named --coacd-timeout."""
    l_shape = trimesh.util.concatenate(
        [trimesh.creation.box((30, 10, 10)), trimesh.creation.box((10, 30, 10)).apply_translation((10, 10, 0))]
    )
    mesh = tmp_path / "l.stl"
    l_shape.export(mesh)
    with pytest.raises(InputError) as e:
        decompose(mesh, DecompositionConfig(timeout_s=0.01), cache_dir=tmp_path / "c")
    assert "--coacd-timeout" in e.value.fix and "--face-budget" in e.value.fix


def test_simplify_to_budget_is_deterministic_and_keeps_the_shape():
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=20.0)  # 20480 faces, mm
    v1, f1 = simplify_to_budget(sphere.vertices, sphere.faces, 1000)
    v2, f2 = simplify_to_budget(sphere.vertices, sphere.faces, 1000)
    assert 200 < len(f1) <= 1000
    np.testing.assert_array_equal(v1, v2)
    np.testing.assert_array_equal(f1, f2)
    simplified = trimesh.Trimesh(v1, f1)
    np.testing.assert_allclose(simplified.extents, sphere.extents, rtol=0.02)
    assert simplified.is_watertight and simplified.volume == pytest.approx(sphere.volume, rel=0.02)
    v, f = simplify_to_budget(sphere.vertices, sphere.faces, 0)
    assert len(f) == len(sphere.faces)
    v, f = simplify_to_budget(sphere.vertices, sphere.faces, 30000)
    assert len(f) == len(sphere.faces)


def test_face_budget_flag_is_checked(capsys, tmp_path):
    code, text = run(capsys, "build", "--variant", "aof", "--face-budget", "-1", "--out", tmp_path / "o")
    assert code == 2 and "--face-budget" in text


def test_progress_names_each_mesh(tmp_path, public_pkg):
    """CoACD's minutes per mesh showed one spinner for all: each mesh now has its progress line
    and its time in the report."""
    from footforge.build import BuildOptions, build

    lines = []
    report = build(
        BuildOptions(
            variant="aof",
            out_dir=tmp_path / "out",
            foot_only=True,
            formats=("mjcf",),
            foot_description=robot_file(public_pkg, "floating_softfoot.urdf.xacro"),
            package_paths=(public_pkg,),
            repair=True,
            cache_dir=tmp_path / "c",
        ),
        progress=lines.append,
    )
    per_mesh = [line for line in lines if line.startswith("decompose collision meshes: ")]
    assert per_mesh[0] == "decompose collision meshes: 1/6 ankle.stl"
    assert len(per_mesh) == 6 and per_mesh[-1].startswith("decompose collision meshes: 6/6 ")
    assert all(m["seconds"] >= 0 for m in report["collision"]["meshes"])
    assert report["collision"]["config"]["face_budget"] == 1000


def test_four_feet_rig_with_the_shipped_sidecar_says_copy_it(capsys, tmp_path, public_pkg):
    """A rig whose foot has another prefix: the shipped sidecar does not fit, and the message says
    to copy it and pass the copy, not to edit footforge's file."""
    rig = robot_file(public_pkg, "floating_softfoot.urdf.xacro")
    four = rig.with_name("four_softfeet.urdf.xacro")
    four.write_text(rig.read_text().replace('name="softfoot"', 'name="softfoot_1"'))
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aof",
        "--foot-only",
        "--repair",
        "--description",
        four,
        "--package-path",
        public_pkg,
        "--out",
        tmp_path / "out",
        "--cache-dir",
        tmp_path / "c",
    )
    assert code == 2, text
    assert "softfoot_1_ankle_base_link" in text and "root_link" in text
    assert "copy" in text and "--sidecar" in text


def test_macro_file_alone_is_explained(capsys, tmp_path, public_pkg):
    """The package's macro file expands to an empty robot: say so, instead of blaming root_link."""
    macros = public_pkg / "softfoot_thing_description" / "model" / "softfoot_thing.urdf.xacro"
    code, text = run(
        capsys,
        "build",
        "--variant",
        "aof",
        "--foot-only",
        "--description",
        macros,
        "--package-path",
        public_pkg,
        "--out",
        tmp_path / "out",
        "--cache-dir",
        tmp_path / "c",
    )
    assert code == 2, text
    assert "no links" in text and "macro" in text and str(macros) in text


def test_sidecar_beside_the_description_wins_over_the_shipped_one(public_pkg):
    from footforge.inputs.sidecar import find_sidecar

    rig = robot_file(public_pkg, "floating_softfoot.urdf.xacro")
    assert find_sidecar(rig) == PUBLIC_SIDECAR
    beside = rig.with_name("floating_softfoot.sidecar.yaml")
    beside.write_text(PUBLIC_SIDECAR.read_text())
    assert find_sidecar(rig) == beside
    assert find_sidecar(REPO / "descriptions/softfoot_q/urdf/softfoot_q.urdf.xacro").name == "softfoot_q.sidecar.yaml"


def test_check_with_the_public_sidecar_closes_the_loops(capsys, public_pkg):
    """`footforge check --sidecar` cuts the rig at root_link too; with the defects fixed by hand,
    the shipped sidecar's three closures close at its reference pose."""
    model = public_pkg / "softfoot_thing_description" / "model"
    for name in ("softfoot_thing.urdf.xacro", "chain_thing.urdf.xacro"):
        path = model / name
        path.write_text(path.read_text().replace('<origin xyz="0 0 0" rpy="0 0 0"/>', ""))
    inertia = model / "softfoot_thing_inertia.xacro"
    inertia.write_text(inertia.read_text().replace('zz="1.0468"', 'zz="4.0468"'))
    code, text = run(
        capsys,
        "check",
        robot_file(public_pkg, "floating_softfoot.urdf.xacro"),
        "--package-path",
        public_pkg,
        "--sidecar",
        PUBLIC_SIDECAR,
    )
    assert code == 0, text
    gaps = [float(line.split("gap ")[1].split(" m")[0]) for line in text.splitlines() if "gap" in line]
    assert len(gaps) == 3 and max(gaps) < 1e-9, text


def test_public_description_validates_with_the_build_flags(capsys, tmp_path, public_pkg):
    """`footforge validate` takes the description flags `build` takes (before: --repair, --arg,
    --face-budget, --coacd-timeout were unknown to validate, so the public foot could be built but
    not validated)."""
    import json

    out = tmp_path / "report"
    code, text = run(
        capsys,
        "validate",
        "--variant",
        "aof",
        "--scenarios",
        "flat_2cm",
        "--jobs",
        "1",
        "--description",
        robot_file(public_pkg, "floating_softfoot.urdf.xacro"),
        "--package-path",
        public_pkg,
        "--repair",
        "--face-budget",
        "1000",
        "--cache-dir",
        tmp_path / "c",
        "--out",
        out,
    )
    report = json.loads((out / "report.json").read_text())
    assert code == (0 if report["passed"] else 1), text
    assert report["inputs"]["foot_description"]["path"].endswith("floating_softfoot.urdf.xacro")
    assert report["runs"]["full"]["flat_2cm"]["scalars"]["final_force_n"] > 0  # the public chain landed


def test_validate_checks_the_description_flags_first(capsys, tmp_path):
    code, text = run(capsys, "validate", "--face-budget", "-1", "--out", tmp_path / "o")
    assert code == 2 and "--face-budget" in text
    assert not (tmp_path / "o").exists()
