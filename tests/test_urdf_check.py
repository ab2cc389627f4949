"""Tests of footforge.inputs.urdf_lint: planted defects, repairs, cross-checks with Pinocchio and MuJoCo."""

import copy
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from footforge.errors import InputError
from footforge.inputs.urdf_lint import (
    Finding,
    check_urdf,
    errors,
    format_findings,
    has_errors,
    read_inertial,
    repair_urdf,
)

# A leg: base -(hip, revolute)-> thigh -(knee, revolute)-> shank -(foot_fixed)-> foot.
# The shank's COM sits on the knee axis (the public SoftFoot-Q puts its chain-link COMs on the
# pins: unusual, not a defect); the thigh's inertial frame is rotated.
VALID_URDF = """\
<robot name="leg">
  <link name="base">
    <inertial>
      <origin xyz="0 0 0.02" rpy="0 0 0"/>
      <mass value="2.0"/>
      <inertia ixx="0.0050" ixy="0" ixz="0" iyy="0.0060" iyz="0" izz="0.0080"/>
    </inertial>
    <visual>
      <origin xyz="0 0 0"/>
      <geometry><mesh filename="meshes/base.stl"/></geometry>
    </visual>
    <collision>
      <geometry><box size="0.2 0.15 0.05"/></geometry>
    </collision>
  </link>
  <link name="thigh">
    <inertial>
      <origin xyz="0 0.01 -0.1" rpy="0.3 -0.2 0.5"/>
      <mass value="0.8"/>
      <inertia ixx="0.0030" ixy="0.0001" ixz="0" iyy="0.0029" iyz="-0.0002" izz="0.0004"/>
    </inertial>
    <visual>
      <geometry><cylinder radius="0.02" length="0.2"/></geometry>
    </visual>
  </link>
  <link name="shank">
    <inertial>
      <origin xyz="0 0 0"/>
      <mass value="0.3"/>
      <inertia ixx="0.0010" ixy="0" ixz="0" iyy="0.0010" iyz="0" izz="0.00005"/>
    </inertial>
  </link>
  <link name="foot">
    <inertial>
      <origin xyz="0 0 -0.01"/>
      <mass value="0.1"/>
      <inertia ixx="0.00002" ixy="0" ixz="0" iyy="0.00002" iyz="0" izz="0.00002"/>
    </inertial>
    <collision>
      <geometry><sphere radius="0.02"/></geometry>
    </collision>
  </link>
  <joint name="hip" type="revolute">
    <origin xyz="0.1 0 0" rpy="0 0 0"/>
    <parent link="base"/>
    <child link="thigh"/>
    <axis xyz="0 1 0"/>
    <limit lower="-1.0" upper="1.0" effort="40" velocity="10"/>
  </joint>
  <joint name="knee" type="revolute">
    <origin xyz="0 0 -0.2"/>
    <parent link="thigh"/>
    <child link="shank"/>
    <axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="0.0" effort="40" velocity="10"/>
  </joint>
  <joint name="foot_fixed" type="fixed">
    <origin xyz="0 0 -0.2"/>
    <parent link="shank"/>
    <child link="foot"/>
  </joint>
</robot>
"""

# The public SoftFoot-Q ankle inertial, Izz typo included.
ANKLE_INERTIAL = """\
<inertial>
  <origin xyz="0 0 0.0154" rpy="0 0 0"/>
  <mass value="0.0181"/>
  <inertia ixx="4.4972e-6" ixy="-0.0012e-6" ixz="-0.0027e-6" iyy="1.8785e-6" iyz="0.0005e-6"
           izz="1.0468e-6"/>
</inertial>
"""


@pytest.fixture
def mesh_dir(tmp_path: Path) -> Path:
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "base.stl").write_text("solid base\nendsolid base\n")
    return tmp_path


@pytest.fixture
def resolve(mesh_dir: Path):
    def resolve_uri(uri: str) -> Path:
        if uri.startswith("package://"):
            package = uri[len("package://") :].partition("/")[0]
            raise InputError(f"cannot find ROS package '{package}'", fix="pass its folder with --package-path")
        return mesh_dir / uri

    return resolve_uri


def valid_root() -> etree._Element:
    return etree.fromstring(VALID_URDF.encode())


def find(root, xpath: str) -> etree._Element:
    (element,) = root.xpath(xpath)
    return element


def planted(edit) -> etree._Element:
    """A copy of the valid URDF with one defect planted by edit(root)."""
    root = valid_root()
    edit(root)
    return root


def set_attr(xpath, name, value):
    return lambda root: find(root, xpath).set(name, value)


def remove(xpath):
    def edit(root):
        element = find(root, xpath)
        element.getparent().remove(element)

    return edit


def append(xpath, xml):
    return lambda root: find(root, xpath).append(etree.fromstring(xml))


def duplicate(xpath):
    def edit(root):
        element = find(root, xpath)
        element.addnext(copy.deepcopy(element))

    return edit


def edits(*functions):
    def edit(root):
        for f in functions:
            f(root)

    return edit


def replace_inertial(link, xml):
    return edits(
        remove(f"/robot/link[@name='{link}']/inertial"),
        lambda root: find(root, f"/robot/link[@name='{link}']").insert(0, etree.fromstring(xml)),
    )


def test_valid_urdf_is_clean(resolve):
    assert check_urdf(valid_root(), resolve_uri=resolve) == []


# (defect, edit, expected codes, element). Each plants exactly one defect.
PLANTED = [
    (
        "non_positive_mass",
        set_attr("//link[@name='thigh']/inertial/mass", "value", "-0.8"),
        {"non_positive_mass"},
        "link 'thigh'",
    ),
    ("non_finite", set_attr("//link[@name='thigh']/inertial/inertia", "iyy", "nan"), {"non_finite"}, "link 'thigh'"),
    (
        "not_positive_definite",
        replace_inertial(
            "shank",
            '<inertial><mass value="0.3"/><inertia ixx="0.001" ixy="0" '
            'ixz="0" iyy="0.001" iyz="0" izz="0"/></inertial>',
        ),
        {"not_positive_definite"},
        "link 'shank'",
    ),
    (
        "triangle_inequality",
        replace_inertial("shank", ANKLE_INERTIAL),
        {"triangle_inequality", "pseudo_inertia_not_psd"},
        "link 'shank'",
    ),
    (
        "unparsable_inertial",
        set_attr("//link[@name='thigh']/inertial/mass", "value", "0,8"),
        {"unparsable_inertial"},
        "link 'thigh'",
    ),
    (
        "unparsable_inertial (missing attribute)",
        lambda root: find(root, "//link[@name='foot']/inertial/inertia").attrib.pop("ixz"),
        {"unparsable_inertial"},
        "link 'foot'",
    ),
    ("inertia_from_geometry", remove("//link[@name='foot']/inertial"), {"inertia_from_geometry"}, "link 'foot'"),
    ("massless_moving_link", remove("//link[@name='thigh']/inertial"), {"massless_moving_link"}, "link 'thigh'"),
    (
        "missing_mesh",
        set_attr("//link[@name='base']/visual/geometry/mesh", "filename", "meshes/Base.stl"),
        {"missing_mesh"},
        "link 'base' visual #1",
    ),
    (
        "unresolved_package",
        set_attr("//link[@name='base']/visual/geometry/mesh", "filename", "package://anymal_c/meshes/base.stl"),
        {"unresolved_package"},
        "link 'base' visual #1",
    ),
    ("repeated origin in joint", duplicate("//joint[@name='knee']/origin"), {"repeated_element"}, "joint 'knee'"),
    ("repeated inertial", duplicate("//link[@name='foot']/inertial"), {"repeated_element"}, "link 'foot'"),
    ("repeated mass", duplicate("//link[@name='foot']/inertial/mass"), {"repeated_element"}, "link 'foot'"),
    (
        "repeated origin in visual",
        duplicate("//link[@name='base']/visual/origin"),
        {"repeated_element"},
        "link 'base' visual #1",
    ),
    (
        "repeated geometry in collision",
        duplicate("//link[@name='foot']/collision/geometry"),
        {"repeated_element"},
        "link 'foot' collision #1",
    ),
    ("repeated limit", duplicate("//joint[@name='hip']/limit"), {"repeated_element"}, "joint 'hip'"),
    (
        "duplicate link name",
        append(
            "/robot",
            '<link name="foot"><inertial><mass value="0.1"/><inertia ixx="1e-5" '
            'ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial></link>',
        ),
        {"duplicate_name"},
        "link 'foot'",
    ),
    (
        "duplicate joint name",
        set_attr("//joint[@name='foot_fixed']", "name", "knee"),
        {"duplicate_name"},
        "joint 'knee'",
    ),
    (
        "dangling_joint",
        set_attr("//joint[@name='knee']/parent", "link", "thigh_link"),
        {"dangling_joint"},
        "joint 'knee'",
    ),
    ("multiple_roots", append("/robot", '<link name="orphan"/>'), {"multiple_roots"}, "robot 'leg'"),
    (
        "two parent joints",
        append("/robot", '<joint name="extra" type="fixed"><parent link="base"/><child link="foot"/></joint>'),
        {"multiple_roots"},
        "link 'foot'",
    ),
    ("missing_limit", remove("//joint[@name='knee']/limit"), {"missing_limit"}, "joint 'knee'"),
    (
        "inverted_limit",
        edits(
            set_attr("//joint[@name='knee']/limit", "lower", "0.5"),
            set_attr("//joint[@name='knee']/limit", "upper", "-0.5"),
        ),
        {"inverted_limit"},
        "joint 'knee'",
    ),
    ("zero_axis", set_attr("//joint[@name='hip']/axis", "xyz", "0 0 0"), {"zero_axis"}, "joint 'hip'"),
]


@pytest.mark.parametrize("name, edit, expected, element", PLANTED, ids=[p[0] for p in PLANTED])
def test_planted_defect_is_found(resolve, name, edit, expected, element):
    findings = check_urdf(planted(edit), resolve_uri=resolve)
    assert {f.code for f in findings} == expected, format_findings(findings)
    assert {f.element for f in findings} == {element}
    for f in findings:
        assert f.message and f.fix
    assert has_errors(findings) == (expected != {"inertia_from_geometry"})


@pytest.mark.parametrize("name, edit, expected, element", PLANTED, ids=[p[0] for p in PLANTED])
def test_repair(resolve, name, edit, expected, element):
    root = planted(edit)
    before = etree.tostring(root)
    findings = check_urdf(root, resolve_uri=resolve)
    repaired, notes = repair_urdf(root, findings)
    assert etree.tostring(root) == before, "repair_urdf must not touch its input"
    after = check_urdf(repaired, resolve_uri=resolve)
    assert not [f for f in after if f.repairable]
    fixable = [f for f in findings if f.repairable]
    if fixable:
        assert after == [], format_findings(after)
        assert notes and all(n.startswith(element) for n in notes)
    else:
        assert notes == []
        assert after == findings  # nothing to do: the caller refuses to build
    # Idempotent.
    again, more_notes = repair_urdf(repaired, after)
    assert more_notes == []
    assert etree.tostring(again) == etree.tostring(repaired)


def test_softfoot_ankle_typo(resolve):
    root = planted(
        edits(
            set_attr("//link[@name='shank']", "name", "ankle"),
            set_attr("//joint[@name='knee']/child", "link", "ankle"),
            set_attr("//joint[@name='foot_fixed']/parent", "link", "ankle"),
            replace_inertial("ankle", ANKLE_INERTIAL),
        )
    )
    findings = check_urdf(root, resolve_uri=resolve)
    triangle = [f for f in findings if f.code == "triangle_inequality"]
    assert len(triangle) == 1 and triangle[0].element == "link 'ankle'"
    assert "4.50e-06 > 1.88e-06 + 1.05e-06" in triangle[0].message
    assert triangle[0].repairable and triangle[0].severity == "error"

    repaired, notes = repair_urdf(root, findings)
    assert notes == [
        "link 'ankle': inertia balanced: principal moments 4.497e-06, 1.878e-06, "
        "1.047e-06 -> 4.497e-06, 1.878e-06, 2.619e-06"
    ]
    inertia = find(repaired, "//link[@name='ankle']/inertial/inertia")
    assert float(inertia.get("izz")) == pytest.approx(4.4972e-6 - 1.8785e-6, rel=1e-3)
    assert float(inertia.get("ixx")) == pytest.approx(4.4972e-6, rel=1e-9)
    assert check_urdf(repaired, resolve_uri=resolve) == []


def test_softfoot_duplicate_joint_origin_keeps_the_first(resolve):
    root = planted(append("//joint[@name='knee']", '<origin xyz="9 9 9" rpy="0 0 0"/>'))
    findings = check_urdf(root, resolve_uri=resolve)
    assert [(f.code, f.element) for f in findings] == [("repeated_element", "joint 'knee'")]
    assert "2 <origin>" in findings[0].message
    repaired, notes = repair_urdf(root, findings)
    assert notes == ["joint 'knee': removed 1 repeated <origin> (kept the first, as ROS does)"]
    assert [o.get("xyz") for o in repaired.xpath("//joint[@name='knee']/origin")] == ["0 0 -0.2"]


def test_chain_link_com_on_the_pin_is_not_a_defect(resolve):
    root = planted(set_attr("//link[@name='thigh']/inertial/origin", "xyz", "0 0 0"))
    assert check_urdf(root, resolve_uri=resolve) == []


def test_massless_marker_and_fixed_mass_carriers(resolve):
    # mass 0 with a zero tensor on a fixed link is an explicit "massless", not a defect; a moving
    # link without inertial is fine when a link fixed to it carries mass.
    root = planted(
        edits(
            replace_inertial(
                "foot",
                '<inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>',
            ),
            remove("//link[@name='foot']/collision"),
        )
    )
    assert check_urdf(root, resolve_uri=resolve) == []
    root = planted(remove("//link[@name='shank']/inertial"))
    assert check_urdf(root, resolve_uri=resolve) == []
    root = planted(
        edits(
            remove("//link[@name='shank']/inertial"),
            remove("//link[@name='foot']/inertial"),
            remove("//link[@name='foot']/collision"),
        )
    )
    findings = check_urdf(root, resolve_uri=resolve)
    assert [(f.code, f.element) for f in findings] == [("massless_moving_link", "link 'shank'")]
    assert "revolute joint 'knee'" in findings[0].message


def test_repair_only_the_findings_given(resolve):
    root = planted(edits(duplicate("//joint[@name='knee']/origin"), duplicate("//joint[@name='hip']/axis")))
    findings = check_urdf(root, resolve_uri=resolve)
    assert len(findings) == 2
    hip = [f for f in findings if f.element == "joint 'hip'"]
    repaired, notes = repair_urdf(root, hip)
    assert len(notes) == 1 and notes[0].startswith("joint 'hip'")
    assert [f.element for f in check_urdf(repaired, resolve_uri=resolve)] == ["joint 'knee'"]
    stranger = Finding("error", "repeated_element", "joint 'ghost'", "x", "y", True)
    with pytest.raises(ValueError, match="ghost"):
        repair_urdf(root, [stranger])


def test_findings_are_sorted_and_formatted(resolve):
    root = planted(
        edits(
            remove("//joint[@name='knee']/limit"),
            set_attr("//joint[@name='hip']/axis", "xyz", "0 0 0"),
            remove("//link[@name='foot']/inertial"),
        )
    )
    findings = check_urdf(root, resolve_uri=resolve)
    assert [(f.element, f.code) for f in findings] == [
        ("joint 'hip'", "zero_axis"),
        ("joint 'knee'", "missing_limit"),
        ("link 'foot'", "inertia_from_geometry"),
    ]
    assert [f.code for f in errors(findings)] == ["zero_axis", "missing_limit"]
    text = format_findings(findings)
    assert text.count("fix: ") == 3
    assert "warning: link 'foot' [inertia_from_geometry]" in text
    assert format_findings([]) == "no findings"


def test_not_a_robot_is_an_input_error(resolve):
    with pytest.raises(InputError):
        check_urdf(etree.fromstring(b"<mujoco/>"), resolve_uri=resolve)


def test_parser_agrees_with_pinocchio():
    """Total mass, and each moving body's mass, COM and inertia, read two ways: our parser
    (read_inertial) and Pinocchio's URDF loader (which merges fixed links into their parent)."""
    import pinocchio as pin

    root = valid_root()
    inertials = {link.get("name"): read_inertial(link) for link in root.findall("link")}
    model = pin.buildModelFromXML(VALID_URDF, pin.JointModelFreeFlyer())
    ours = sum(i.mass for i in inertials.values())
    assert pin.computeTotalMass(model) == pytest.approx(ours, rel=1e-12)
    assert ours == pytest.approx(3.2)

    thigh = model.inertias[model.getJointId("hip")]
    assert thigh.mass == pytest.approx(inertials["thigh"].mass)
    np.testing.assert_allclose(thigh.lever, inertials["thigh"].xyz, atol=1e-15)
    np.testing.assert_allclose(thigh.inertia, inertials["thigh"].inertia_in_link_frame(), atol=1e-15)

    # shank + foot (fixed 0.2 m below the knee) merged, by pin.Inertia arithmetic.
    shank, foot = inertials["shank"], inertials["foot"]
    merged = pin.Inertia(shank.mass, np.array(shank.xyz), shank.inertia_in_link_frame()) + pin.SE3(
        np.eye(3), np.array([0, 0, -0.2])
    ).act(pin.Inertia(foot.mass, np.array(foot.xyz), foot.inertia_in_link_frame()))
    assert model.inertias[model.getJointId("knee")].isApprox(merged, 1e-12)


def test_mujoco_agrees_on_defects_and_repairs(resolve):
    """MuJoCo's compiler rejects what check_urdf reports, and accepts what repair_urdf returns."""
    import mujoco

    def mujoco_error(root) -> str | None:
        try:
            mujoco.MjModel.from_xml_string(etree.tostring(root).decode())
        except ValueError as e:
            return str(e)
        return None

    assert mujoco_error(valid_root()) is None
    cases = [
        (replace_inertial("shank", ANKLE_INERTIAL), "A + B >= C"),
        (
            replace_inertial(
                "shank",
                '<inertial><mass value="0.3"/><inertia ixx="0.003" ixy="0" '
                'ixz="0" iyy="0" iyz="0" izz="0"/></inertial>',
            ),
            "positive eigenvalues",
        ),
        (duplicate("//joint[@name='knee']/origin"), "repeated element"),
    ]
    for edit, message in cases:
        root = planted(edit)
        assert message in mujoco_error(root)
        repaired, _ = repair_urdf(root, check_urdf(root, resolve_uri=resolve))
        assert mujoco_error(repaired) is None
    # Not repairable, and MuJoCo cannot build it either.
    root = planted(remove("//link[@name='thigh']/inertial"))
    assert [f.code for f in check_urdf(root, resolve_uri=resolve)] == ["massless_moving_link"]
    assert "mass and inertia of moving bodies" in mujoco_error(root)
