"""Checks on an expanded URDF before it is turned into a simulation model, and their repairs.

Each loader forgives different mistakes, silently: Pinocchio loads an inertia that breaks the
triangle inequality and treats an `<inertial>` it cannot parse as massless; ROS takes the first
of repeated `<origin>` elements where MuJoCo rejects the file; MuJoCo invents the inertia of a
link without `<inertial>` from its collision geoms (ANYmal C's base grows to 55.7 kg that way).
`check_urdf` reports all of these as `Finding`s that name the element, give the values and a
concrete fix; `repair_urdf` applies the repairs that have one right answer and leaves the rest
to the user.

Findings (severity; repairable or not):

* per link with an `<inertial>`: the criteria of `footforge.inputs.inertia` (`non_positive_mass`,
  `non_finite`: errors, not repairable; `not_symmetric`, `not_positive_definite`,
  `triangle_inequality`, `pseudo_inertia_not_psd`: errors, repaired by `balance_inertia`);
  `unparsable_inertial` (error) for a missing or malformed number. An inertial of mass 0 with an
  all-zero tensor is read as an explicit "massless" marker (common for frames), not a defect.
* `inertia_from_geometry` (warning): collision geoms but no `<inertial>`; MuJoCo would infer a
  mass from the geoms, footforge treats the link as massless.
* `massless_moving_link` (error): the child of a moving joint carries no mass, on itself or on
  links fixed to it; MuJoCo cannot simulate a massless moving body.
* `missing_mesh`, `unresolved_package` (errors): a mesh file that is not there, or whose
  `package://` package cannot be found. `unusable_collision_mesh` (error): a collision mesh that
  cannot be read, has no faces or is flat (no volume: no convex hull, so the build would fail).
* `repeated_element` (error, repairable: the first is kept, as ROS does): an element URDF allows
  once (for example two `<origin>` in a joint). `duplicate_name`, `missing_name` (errors).
* `dangling_joint`, `multiple_roots` (also for a link with two parent joints), `no_root`
  (errors): the links and joints do not form one tree.
* `missing_limit`, `inverted_limit`, `zero_axis`, `unknown_joint_type`, `unparsable_joint`
  (errors): joint sanity.
"""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal, cast

import numpy as np
from lxml import etree

from footforge.errors import CheckFailure, InputError
from footforge.inputs.description import Description
from footforge.inputs.inertia import balance_inertia, inertia_defects, principal_moments

Severity = Literal["error", "warning"]

JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
MOVING_JOINT_TYPES = ("revolute", "continuous", "prismatic", "floating", "planar")
INERTIA_ATTRIBUTES = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")

SINGLE_CHILDREN = {
    "link": ("inertial",),
    "inertial": ("origin", "mass", "inertia"),
    "visual": ("origin", "geometry", "material"),
    "collision": ("origin", "geometry"),
    "joint": ("origin", "parent", "child", "axis", "limit", "dynamics", "mimic", "calibration", "safety_controller"),
}
"""Children that URDF allows at most once, per parent element."""

_REPAIRABLE_INERTIA = ("not_symmetric", "not_positive_definite", "triangle_inequality", "pseudo_inertia_not_psd")

_INERTIA_FIXES = {
    "non_positive_mass": "set <mass value> to the part's mass in kg (> 0); for a massless frame "
    "remove the <inertial> and attach the link with a fixed joint",
    "non_finite": "replace the nan/inf value with the CAD value",
    "not_symmetric": "use one value for each off-diagonal pair (Ixy = Iyx, ...)",
    "not_positive_definite": "take the inertia from CAD (about the COM, in the inertial frame); "
    "--repair (footforge build) raises the zero or negative principal moments to a tiny "
    "positive floor",
    "triangle_inequality": "compare the moments with CAD (a dropped digit is the usual cause); "
    "--repair (footforge build) raises the smallest principal moment to the difference "
    "of the other two",
    "pseudo_inertia_not_psd": "no mass distribution has these moments: take them from CAD; "
    "--repair (footforge build) balances the principal moments",
}


@dataclass(frozen=True)
class Finding:
    """One problem found in a URDF."""

    severity: Severity
    """"error": the model must not be built from the file as is; "warning": it can be, but a
    loader may read it differently from footforge."""
    code: str
    """Machine-readable kind, e.g. "triangle_inequality" (see the module docstring)."""
    element: str
    """Where, e.g. "link 'ankle'", "joint 'front_roll'", "link 'base' visual #1"."""
    message: str
    """What is wrong, with the values."""
    fix: str
    """A concrete suggestion."""
    repairable: bool
    """Whether `repair_urdf` fixes it."""


@dataclass(frozen=True)
class Inertial:
    """The `<inertial>` of a link as URDF states it (the first of each element, as ROS reads)."""

    mass: float
    """kg."""
    xyz: tuple[float, float, float]
    """Centre of mass in the link frame (the inertial origin), metres."""
    rpy: tuple[float, float, float]
    """Orientation of the inertial frame in the link frame (URDF roll-pitch-yaw), radians."""
    moments: tuple[float, float, float, float, float, float]
    """ixx, ixy, ixz, iyy, iyz, izz about the COM in the inertial frame, kg·m²."""

    def inertia(self) -> np.ndarray:
        """(3, 3) inertia about the COM in the inertial frame, as written."""
        ixx, ixy, ixz, iyy, iyz, izz = self.moments
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])

    def inertia_in_link_frame(self) -> np.ndarray:
        """(3, 3) inertia about the COM in the link's axes: R I Rᵀ with R from rpy."""
        rotation = rpy_matrix(self.rpy)
        return rotation @ self.inertia() @ rotation.T

    def is_massless_marker(self) -> bool:
        """Mass 0 and an all-zero tensor: an explicit "this link has no mass"."""
        return self.mass == 0.0 and not any(self.moments)


def rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    """Rotation matrix of URDF roll-pitch-yaw angles: Rz(yaw) @ Ry(pitch) @ Rx(roll)."""
    roll, pitch, yaw = rpy
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _number(text: str | None, what: str, problems: list[str]) -> float:
    if text is None:
        problems.append(f"{what} is missing")
        return 0.0
    try:
        return float(text)
    except ValueError:
        problems.append(f"{what} = '{text}' is not a number")
        return 0.0


def _vector(text: str | None, what: str, problems: list[str]) -> tuple[float, float, float]:
    if text is None:
        return (0.0, 0.0, 0.0)
    parts = text.split()
    if len(parts) != 3:
        problems.append(f"{what} = '{text}' is not three numbers")
        return (0.0, 0.0, 0.0)
    values = tuple(_number(p, what, problems) for p in parts)
    return values  # type: ignore[return-value]


def read_inertial(link: etree._Element) -> Inertial | None:
    """Reads the first `<inertial>` of a `<link>` element.

    Args:
      link: a `<link>` element.

    Returns:
      The inertial, or None when the link has none.

    Raises:
      InputError: a required element or attribute is missing or a number is malformed (all
        problems in one message); Pinocchio would load such a link as massless.
    """
    inertial = link.find("inertial")
    if inertial is None:
        return None
    problems: list[str] = []
    origin = inertial.find("origin")
    xyz = _vector(origin.get("xyz") if origin is not None else None, "<origin xyz>", problems)
    rpy = _vector(origin.get("rpy") if origin is not None else None, "<origin rpy>", problems)
    mass_el = inertial.find("mass")
    if mass_el is None:
        problems.append("<mass> is missing")
        mass = 0.0
    else:
        mass = _number(mass_el.get("value"), "<mass value>", problems)
    inertia_el = inertial.find("inertia")
    if inertia_el is None:
        problems.append("<inertia> is missing")
        moments: tuple[float, ...] = (0.0,) * 6
    else:
        moments = tuple(_number(inertia_el.get(a), f"<inertia {a}>", problems) for a in INERTIA_ATTRIBUTES)
    if problems:
        raise InputError(
            "; ".join(problems),
            element=_link_label(link),
            fix="give <mass value> and all six of ixx, ixy, ixz, iyy, iyz, izz "
            "as numbers (origin xyz and rpy as three numbers each)",
        )
    return Inertial(mass=mass, xyz=xyz, rpy=rpy, moments=moments)  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------------------
# Detection. Each detector yields _Items on the tree it is given; a repairable item carries the
# action that repairs it on that tree. repair_urdf reruns the detectors on a copy and applies the
# actions of the findings it was asked to repair.


@dataclass
class _Item:
    finding: Finding
    key: tuple = ()
    """Actions with equal keys are applied once (several inertia findings, one balancing)."""
    action: Callable[[], str] | None = None
    """Repairs the tree; returns a note."""


def _link_label(link: etree._Element) -> str:
    name = link.get("name")
    if name is None:
        return f"link at line {link.sourceline}" if link.sourceline else "unnamed link"
    return f"link '{name}'"


def _joint_label(joint: etree._Element) -> str:
    name = joint.get("name")
    if name is None:
        return f"joint at line {joint.sourceline}" if joint.sourceline else "unnamed joint"
    return f"joint '{name}'"


def _error(code: str, element: str, message: str, fix: str, *, repairable: bool = False) -> Finding:
    return Finding("error", code, element, message, fix, repairable)


def _repeated_items(container: etree._Element, label: str, where: str) -> list[_Item]:
    items = []
    for tag in SINGLE_CHILDREN[container.tag]:
        found = container.findall(tag)
        if len(found) < 2:
            continue
        extra = found[1:]

        def remove(extra=extra, tag=tag, label=label, where=where) -> str:
            for element in extra:
                element.getparent().remove(element)
            return f"{label}: removed {len(extra)} repeated <{tag}> {where}(kept the first, as ROS does)"

        finding = _error(
            "repeated_element",
            label,
            f"{len(found)} <{tag}> elements {where}(URDF allows one: ROS takes the first, MuJoCo rejects the file)",
            f"keep one <{tag}> {where}and delete the others (footforge build --repair keeps the first)",
            repairable=True,
        )
        items.append(_Item(finding, key=("repeated", container, tag), action=remove))
    return items


def _structure_items(root: etree._Element) -> list[_Item]:
    items: list[_Item] = []
    links = root.findall("link")
    joints = root.findall("joint")

    for kind, elements, label_of in (("link", links, _link_label), ("joint", joints, _joint_label)):
        seen: dict[str, int] = {}
        for element in elements:
            name = element.get("name")
            if not name:
                items.append(
                    _Item(
                        _error(
                            "missing_name",
                            label_of(element),
                            f"<{kind}> has no name attribute",
                            f"give every <{kind}> a unique name",
                        )
                    )
                )
                continue
            seen[name] = seen.get(name, 0) + 1
        for name, count in seen.items():
            if count > 1:
                items.append(
                    _Item(
                        _error(
                            "duplicate_name",
                            f"{kind} '{name}'",
                            f"{count} {kind}s are named '{name}'",
                            f"rename all but one {kind} '{name}' (and the joints that refer to it)",
                        )
                    )
                )

    for link in links:
        label = _link_label(link)
        items += _repeated_items(link, label, "")
        inertial = link.find("inertial")
        if inertial is not None:
            items += _repeated_items(inertial, label, "in <inertial> ")
        for kind in ("visual", "collision"):
            for index, element in enumerate(link.findall(kind), start=1):
                items += _repeated_items(element, f"{label} {kind} #{index}", "")

    for joint in joints:
        items += _repeated_items(joint, _joint_label(joint), "")
    return items


def _inertia_items(root: etree._Element) -> list[_Item]:
    items: list[_Item] = []
    for link in root.findall("link"):
        label = _link_label(link)
        try:
            inertial = read_inertial(link)
        except InputError as e:
            items.append(
                _Item(
                    _error(
                        "unparsable_inertial",
                        label,
                        f"{e.message} (Pinocchio would load this link as massless)",
                        e.fix or "",
                    )
                )
            )
            continue
        if inertial is None or inertial.is_massless_marker():
            continue
        defects = inertia_defects(inertial.mass, inertial.xyz, inertial.inertia_in_link_frame())
        inertia_el = link.find("inertial").find("inertia")
        for defect in defects:
            repairable = defect.code in _REPAIRABLE_INERTIA
            finding = _error(defect.code, label, defect.message, _INERTIA_FIXES[defect.code], repairable=repairable)
            if repairable:
                items.append(
                    _Item(finding, key=("balance", inertia_el), action=functools.partial(_balance, inertia_el, label))
                )
            else:
                items.append(_Item(finding))
    return items


def _balance(inertia_el: etree._Element, label: str) -> str:
    values = [float(inertia_el.get(a)) for a in INERTIA_ATTRIBUTES]
    ixx, ixy, ixz, iyy, iyz, izz = values
    before = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    after = balance_inertia(before)
    new = (after[0, 0], after[0, 1], after[0, 2], after[1, 1], after[1, 2], after[2, 2])
    for attribute, value in zip(INERTIA_ATTRIBUTES, new):
        inertia_el.set(attribute, repr(float(value)))
    old_moments = ", ".join(f"{v:.4g}" for v in principal_moments(before)[0])
    new_moments = ", ".join(f"{v:.4g}" for v in principal_moments(after)[0])
    return f"{label}: inertia balanced: principal moments {old_moments} -> {new_moments}"


def _parse_joint(joint: etree._Element) -> tuple[str | None, str | None, str | None]:
    parent = joint.find("parent")
    child = joint.find("child")
    return (
        joint.get("type"),
        parent.get("link") if parent is not None else None,
        child.get("link") if child is not None else None,
    )


def _tree_items(root: etree._Element) -> list[_Item]:
    items: list[_Item] = []
    links: dict[str, etree._Element] = {
        link.get("name"): link for link in reversed(root.findall("link")) if link.get("name")
    }  # reversed: the first of duplicates wins, as in ROS
    parents_of: dict[str, list[str]] = {}
    fixed_children: dict[str, list[str]] = {}
    moving: list[tuple[str, str, str]] = []  # (joint label, type, child)

    for joint in root.findall("joint"):
        label = _joint_label(joint)
        jtype, parent, child = _parse_joint(joint)
        for role, name in (("parent", parent), ("child", child)):
            if name is None:
                items.append(
                    _Item(
                        _error(
                            "dangling_joint",
                            label,
                            f"no <{role} link=...>",
                            f'add <{role} link="..."/> naming an existing link',
                        )
                    )
                )
            elif name not in links:
                items.append(
                    _Item(
                        _error(
                            "dangling_joint",
                            label,
                            f"{role} link '{name}' does not exist",
                            f'correct the {role} link name or add <link name="{name}">',
                        )
                    )
                )
        if child in links:
            parents_of.setdefault(child, []).append(label)
        if jtype not in JOINT_TYPES:
            items.append(
                _Item(
                    _error(
                        "unknown_joint_type",
                        label,
                        f"type '{jtype}' is not a URDF joint type",
                        f"use one of {', '.join(JOINT_TYPES)}",
                    )
                )
            )
        elif jtype == "fixed":
            if parent in links and child in links:
                fixed_children.setdefault(parent, []).append(child)
        elif child in links:
            moving.append((label, jtype, child))
        items += _joint_sanity_items(joint, label, jtype)

    children = set(parents_of)
    roots = [name for name in links if name not in children]
    if len(roots) > 1:
        listing = ", ".join(f"'{r}'" for r in sorted(roots))
        items.append(
            _Item(
                _error(
                    "multiple_roots",
                    f"robot '{root.get('name', '')}'",
                    f"{len(roots)} root links (no joint has them as child): {listing}",
                    "attach every link but the base to the tree with a joint, or remove it",
                )
            )
        )
    elif not roots and links:
        items.append(
            _Item(
                _error(
                    "no_root",
                    f"robot '{root.get('name', '')}'",
                    "no root link: every link is some joint's child (the joints form a loop)",
                    "a URDF is a tree: break the loop and close it in the simulator instead",
                )
            )
        )
    for child, labels in sorted(parents_of.items()):
        if len(labels) > 1:
            items.append(
                _Item(
                    _error(
                        "multiple_roots",
                        f"link '{child}'",
                        f"child of {len(labels)} joints: {', '.join(labels)}",
                        "a URDF is a tree: keep one parent joint and close the loop in the simulator "
                        "(as the SoftFoot-Q chain closures are)",
                    )
                )
            )

    items += _massless_items(links, fixed_children, moving)
    return items


def _joint_sanity_items(joint: etree._Element, label: str, jtype: str | None) -> list[_Item]:
    items: list[_Item] = []
    problems: list[str] = []
    origin = joint.find("origin")
    if origin is not None:
        _vector(origin.get("xyz"), "<origin xyz>", problems)
        _vector(origin.get("rpy"), "<origin rpy>", problems)
    if jtype in ("revolute", "continuous", "prismatic", "planar"):
        axis = joint.find("axis")
        if axis is not None:
            xyz = _vector(axis.get("xyz", "1 0 0"), "<axis xyz>", problems)
            if not problems and math.sqrt(sum(v * v for v in xyz)) < 1e-12:
                items.append(
                    _Item(
                        _error(
                            "zero_axis",
                            label,
                            f"axis xyz = '{axis.get('xyz')}' has zero length",
                            'give the joint axis as a non-zero vector, e.g. <axis xyz="0 1 0"/>',
                        )
                    )
                )
    if jtype in ("revolute", "prismatic"):
        limit = joint.find("limit")
        if limit is None:
            unit = "rad" if jtype == "revolute" else "m"
            items.append(
                _Item(
                    _error(
                        "missing_limit",
                        label,
                        f"{jtype} joint without <limit> (URDF requires one)",
                        f'add <limit lower="..." upper="..." effort="..." velocity="..."/> '
                        f"({unit}), or make the joint continuous",
                    )
                )
            )
        else:
            count = len(problems)
            lower = _number(limit.get("lower", "0"), "<limit lower>", problems)
            upper = _number(limit.get("upper", "0"), "<limit upper>", problems)
            if len(problems) == count and lower > upper:
                items.append(
                    _Item(_error("inverted_limit", label, f"lower {lower:g} > upper {upper:g}", "swap lower and upper"))
                )
    if problems:
        items.append(
            _Item(
                _error(
                    "unparsable_joint",
                    label,
                    "; ".join(problems),
                    "write each vector as three numbers and each limit as a number",
                )
            )
        )
    return items


def _massless_items(
    links: dict[str, etree._Element], fixed_children: dict[str, list[str]], moving: list[tuple[str, str, str]]
) -> list[_Item]:
    def carries_mass(name: str) -> bool:
        # Unparsable or defective inertials count as mass: they are reported on their own.
        try:
            inertial = read_inertial(links[name])
        except InputError:
            return True
        return inertial is not None and not inertial.is_massless_marker()

    def group_has_mass(name: str, seen: set[str]) -> bool:
        if name in seen:
            return False
        seen.add(name)
        return carries_mass(name) or any(group_has_mass(c, seen) for c in fixed_children.get(name, ()))

    items = []
    for joint_label, jtype, child in moving:
        if not group_has_mass(child, set()):
            items.append(
                _Item(
                    _error(
                        "massless_moving_link",
                        f"link '{child}'",
                        f"moved by {jtype} {joint_label} but carries no mass (no <inertial> on it or "
                        "on the links fixed to it); MuJoCo cannot simulate a massless moving body",
                        f"add an <inertial> with the part's mass and inertia, or make {joint_label} fixed",
                    )
                )
            )
    return items


def _geometry_items(root: etree._Element) -> list[_Item]:
    items = []
    for link in root.findall("link"):
        if link.find("collision") is not None and link.find("inertial") is None:
            items.append(
                _Item(
                    Finding(
                        "warning",
                        "inertia_from_geometry",
                        _link_label(link),
                        "collision geoms but no <inertial>: MuJoCo infers a mass from the geoms unless "
                        "inertiafromgeom is off; footforge treats the link as massless",
                        "add an <inertial> with the part's mass, COM and inertia (or confirm that the "
                        "link is massless)",
                        False,
                    )
                )
            )
    return items


def _mesh_items(root: etree._Element, resolve_uri: Callable[[str], Path]) -> list[_Item]:
    items = []
    cache: dict[str, Path | InputError] = {}
    for link in root.findall("link"):
        for kind in ("visual", "collision"):
            for index, element in enumerate(link.findall(kind), start=1):
                label = f"{_link_label(link)} {kind} #{index}"
                for mesh in element.findall("geometry/mesh"):
                    uri = mesh.get("filename")
                    if not uri:
                        items.append(
                            _Item(
                                _error(
                                    "missing_mesh",
                                    label,
                                    "<mesh> has no filename",
                                    'give the mesh file as filename="package://pkg/meshes/part.stl"',
                                )
                            )
                        )
                        continue
                    if uri not in cache:
                        try:
                            cache[uri] = Path(resolve_uri(uri))
                        except InputError as e:
                            cache[uri] = e
                    resolved = cache[uri]
                    if isinstance(resolved, InputError):
                        items.append(
                            _Item(
                                _error(
                                    "unresolved_package",
                                    label,
                                    f"mesh '{uri}': {resolved.message}",
                                    resolved.fix or "pass the package's folder on the package path",
                                )
                            )
                        )
                    elif not resolved.is_file():
                        items.append(
                            _Item(
                                _error(
                                    "missing_mesh",
                                    label,
                                    f"mesh '{uri}' resolves to {resolved}, which does not exist",
                                    "check the file name, its case and the package's meshes folder",
                                )
                            )
                        )
                    elif kind == "collision":
                        problem = _collision_mesh_problem(resolved, mesh.get("scale"))
                        if problem:
                            items.append(
                                _Item(
                                    _error(
                                        "unusable_collision_mesh",
                                        label,
                                        f"mesh '{uri}': {problem}",
                                        "export a closed solid mesh, or remove this <collision> element",
                                    )
                                )
                            )
    return items


def _collision_mesh_problem(path: Path, scale: str | None) -> str | None:
    """Why the collision mesh at `path` cannot be built (footforge.inputs.meshes.flat_mesh_problem)."""
    import trimesh

    from footforge.inputs.meshes import flat_mesh_problem

    try:
        mesh = cast(trimesh.Trimesh, trimesh.load(path, force="mesh"))  # force="mesh": one Trimesh
    except Exception as e:  # trimesh raises many kinds for a malformed file
        return f"cannot be read ({e})"
    try:
        factor = min(abs(float(x)) for x in scale.split()) if scale else 1.0
    except ValueError:
        factor = 1.0
    return flat_mesh_problem(mesh, factor)


def _repairable_scope_items(root: etree._Element) -> list[_Item]:
    return _structure_items(root) + _inertia_items(root)


def _sort_key(finding: Finding) -> tuple[str, str, str]:
    return (finding.element, finding.code, finding.message)


def check_urdf(root: etree._Element, *, resolve_uri: Callable[[str], Path]) -> list[Finding]:
    """Checks an expanded URDF for physical, structural and file problems.

    Args:
      root: the `<robot>` element (after xacro expansion).
      resolve_uri: returns the file path of a mesh URI; raises InputError when the URI's package
        cannot be found (`Description.resolve_uri` does both).

    Returns:
      The findings, sorted by element, then code, then message (the codes are listed in the
      module docstring); empty for a clean file.

    Raises:
      InputError: root is not a `<robot>` element.
    """
    if root.tag != "robot":
        raise InputError(
            f"root element is <{root.tag}>, not <robot>", fix="pass the <robot> element of an expanded URDF"
        )
    items = _repairable_scope_items(root) + _tree_items(root) + _geometry_items(root) + _mesh_items(root, resolve_uri)
    return sorted((item.finding for item in items), key=_sort_key)


def repair_urdf(root: etree._Element, findings: Iterable[Finding]) -> tuple[etree._Element, list[str]]:
    """Applies the repairs of the repairable findings to a copy of the tree.

    Repeated elements: all but the first are removed (ROS reads the first). Inertia defects:
    the `<inertia>` is replaced by `balance_inertia` of it, written with full precision (repr).
    Non-repairable findings are skipped: the caller must refuse to build while they remain.
    Repeated elements are removed before inertias are balanced. Repairing the findings of
    `check_urdf(root)` leaves a tree whose check has no repairable finding.

    Args:
      root: the `<robot>` element the findings were computed on; not modified.
      findings: findings of `check_urdf(root, ...)`, or a subset of them to repair only those.

    Returns:
      (repaired copy, notes): one human-readable note per change, e.g. "link 'ankle': inertia
      balanced: principal moments 4.497e-06, 1.878e-06, 1.047e-06 -> 4.497e-06, 1.878e-06,
      2.619e-06".

    Raises:
      ValueError: a repairable finding does not occur in this tree.
    """
    repaired = copy.deepcopy(root)
    wanted = {f for f in findings if f.repairable}
    items = _repairable_scope_items(repaired)
    unknown = wanted - {item.finding for item in items}
    if unknown:
        listing = "; ".join(f"{f.element}: {f.code}" for f in sorted(unknown, key=_sort_key))
        raise ValueError(f"findings not found in this tree: {listing}")
    actions: dict[tuple, Callable[[], str]] = {}
    for item in items:
        if item.finding in wanted and item.action is not None:
            actions.setdefault(item.key, item.action)
    # Structure first (the balancing reads the first <inertia>, which dedup keeps).
    ordered = sorted(actions.items(), key=lambda kv: kv[0][0] != "repeated")
    return repaired, [action() for _, action in ordered]


def errors(findings: Iterable[Finding]) -> list[Finding]:
    """The findings of severity "error"."""
    return [f for f in findings if f.severity == "error"]


def has_errors(findings: Iterable[Finding]) -> bool:
    """Whether any finding is an error."""
    return any(f.severity == "error" for f in findings)


def format_findings(findings: Iterable[Finding]) -> str:
    """Text for a terminal: one block per finding (severity, element, code, message, fix).

    Args:
      findings: as returned by `check_urdf`.

    Returns:
      The blocks separated by blank lines; "no findings" when there are none.
    """
    blocks = []
    for f in findings:
        tag = f"{f.code}, repairable" if f.repairable else f.code
        blocks.append(f"{f.severity}: {f.element} [{tag}]\n  {f.message}\n  fix: {f.fix}")
    return "\n\n".join(blocks) if blocks else "no findings"


INPUT_ERROR_CODES = frozenset({"missing_mesh", "unresolved_package"})


def lint_and_repair(
    description: Description, *, repair: bool, what: str
) -> tuple[Description, list[Finding], list[str]]:
    """Runs `check` on a description; repairs it if asked; refuses one with errors.

    Raises:
      CheckFailure: errors remain (all of them are listed, with fixes).
    """
    findings = check_urdf(description.root(), resolve_uri=description.resolve_uri)
    notes: list[str] = []
    if has_errors(findings) and repair:
        repaired, notes = repair_urdf(description.root(), findings)
        description = replace(description, urdf=etree.tostring(repaired, encoding="unicode"))
        findings = check_urdf(description.root(), resolve_uri=description.resolve_uri)
    missing = [f for f in findings if f.severity == "error" and f.code in INPUT_ERROR_CODES]
    if missing:  # files that are not there are input errors (exit 2), not model defects
        raise InputError(
            f"the {what} description refers to files it cannot find:\n{format_findings(missing)}",
            file=str(description.source),
            fix="fix the paths, or add the folder holding the package with --package-path",
        )
    if has_errors(findings):
        repairable = all(f.repairable for f in findings if f.severity == "error")
        raise CheckFailure(
            f"the {what} description has errors:\n{format_findings([f for f in findings if f.severity == 'error'])}",
            file=str(description.source),
            fix=(
                "rerun with --repair to apply the listed repairs (recorded in the build report)"
                if repairable
                else "fix the description as suggested above"
            ),
        )
    return description, findings, notes


def link_inertia_checks(description: Description, findings: list[Finding]) -> dict[str, str]:
    """Per link with an inertial: 'ok' or the codes of its inertia findings."""
    by_link: dict[str, list[str]] = {}
    for f in findings:
        if f.element.startswith("link '"):
            by_link.setdefault(f.element.split("'")[1], []).append(f.code)
    out = {}
    for link in description.root().findall("link"):
        if link.find("inertial") is not None:
            codes = by_link.get(link.get("name"), [])
            out[link.get("name")] = "ok" if not codes else ", ".join(codes)
    return out
