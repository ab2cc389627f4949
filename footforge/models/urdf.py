"""URDF -> the kinematic tree as Pinocchio parses it (footforge.mjcf.elements maps it onto MJCF).

Pinocchio parses the URDF: its kinematic tree, the inertia of each moving body with fixed-attached
links merged in by rigid-body algebra (`pin.Inertia` sums), and the collision and visual geometry
(through coal). MuJoCo's own URDF importer is not used because its XML export rounds to six
digits, which would break footforge's 1e-9 mass-property checks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from lxml import etree

from footforge.errors import InputError
from footforge.inputs.description import Description

FLOATING_JOINT = "root_joint"  # Pinocchio's name for the free-flyer it adds at the root

_AXIS_OF_SHORTNAME = {
    "JointModelRX": (1.0, 0.0, 0.0),
    "JointModelRY": (0.0, 1.0, 0.0),
    "JointModelRZ": (0.0, 0.0, 1.0),
    "JointModelPX": (1.0, 0.0, 0.0),
    "JointModelPY": (0.0, 1.0, 0.0),
    "JointModelPZ": (0.0, 0.0, 1.0),
    "JointModelRUBX": (1.0, 0.0, 0.0),
    "JointModelRUBY": (0.0, 1.0, 0.0),
    "JointModelRUBZ": (0.0, 0.0, 1.0),
}


def quat_wxyz(rotation: np.ndarray) -> np.ndarray:
    """MuJoCo's quaternion (w, x, y, z) of a rotation matrix, with w >= 0."""
    q = pin.Quaternion(np.asarray(rotation, dtype=float))
    wxyz = np.array([q.w, q.x, q.y, q.z])
    return wxyz if wxyz[0] >= 0 else -wxyz


def joint_axis(jmodel) -> np.ndarray:
    name = jmodel.shortname()
    if name in _AXIS_OF_SHORTNAME:
        return np.array(_AXIS_OF_SHORTNAME[name])
    concrete = jmodel.extract()
    if hasattr(concrete, "axis"):
        return np.asarray(concrete.axis, dtype=float)
    raise InputError(f"unsupported joint type {name}", fix="use revolute, continuous, prismatic or fixed joints")


def joint_kind(jmodel) -> str:
    name = jmodel.shortname()
    if name == "JointModelFreeFlyer":
        return "free"
    if "RevoluteUnbounded" in name or name.startswith("JointModelRUB"):
        return "continuous"
    if "Revolute" in name or name in ("JointModelRX", "JointModelRY", "JointModelRZ"):
        return "hinge"
    if "Prismatic" in name or name in ("JointModelPX", "JointModelPY", "JointModelPZ"):
        return "slide"
    raise InputError(f"unsupported joint type {name}", fix="use revolute, continuous, prismatic or fixed joints")


@dataclass
class ParsedURDF:
    """A URDF parsed by Pinocchio, with the URDF's own names and order kept alongside."""

    description: Description
    urdf: str
    """URDF text with mesh URIs rewritten to absolute file paths."""
    model: pin.Model
    collision: pin.GeometryModel
    visual: pin.GeometryModel
    root_link: str
    link_of_joint: dict[str, str]
    """Pinocchio joint name -> the link it moves (the root joint moves the root link)."""
    child_order: dict[str, int]
    """Link name -> its position in the URDF, to emit bodies in document order."""
    mimics: tuple[tuple[str, str, float, float], ...]
    """(joint, followed joint, multiplier, offset) of every URDF <mimic>."""

    def joint_id(self, name: str) -> int:
        if not self.model.existJointName(name):
            raise InputError(
                f"no joint named '{name}' in the description",
                file=str(self.description.source),
                element=f"joint '{name}'",
                fix="check the name against the URDF",
            )
        return self.model.getJointId(name)

    def body_of_link(self, link: str) -> tuple[int, pin.SE3]:
        """Pinocchio joint id that carries `link`, and the link frame's placement in it."""
        if not self.model.existFrame(link, pin.BODY):
            raise InputError(
                f"no link named '{link}' in the description",
                file=str(self.description.source),
                element=f"link '{link}'",
                fix="check the name against the URDF",
            )
        frame = self.model.frames[self.model.getFrameId(link, pin.BODY)]
        return frame.parentJoint, frame.placement

    def link_of(self, joint_id: int) -> str:
        return self.link_of_joint[self.model.names[joint_id]]


def parse_urdf(description: Description, *, floating: bool) -> ParsedURDF:
    """Parses an expanded description with Pinocchio.

    Args:
      description: the expanded URDF and where to resolve its mesh URIs.
      floating: give the root a free-flyer joint (a robot's base, or a foot to be mounted later).

    Raises:
      InputError: unresolved packages, missing meshes, or a URDF Pinocchio rejects.
    """
    root = description.root()
    for mesh in root.iter("mesh"):
        uri = mesh.get("filename", "")
        path = description.resolve_uri(uri)
        if not path.is_file():
            owner = mesh.getparent().getparent()
            link = owner.getparent()
            raise InputError(
                f"mesh file not found: {path}",
                file=str(description.source),
                element=f"link '{link.get('name')}' {owner.tag} mesh '{uri}'",
                fix="fix the filename, or add the folder holding the package with --package-path",
            )
        mesh.set("filename", str(path.resolve()))
    urdf = etree.tostring(root, encoding="unicode")
    try:
        if floating:
            model = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer())
        else:
            model = pin.buildModelFromXML(urdf)
        collision = pin.buildGeomFromUrdfString(model, urdf, pin.COLLISION)
        visual = pin.buildGeomFromUrdfString(model, urdf, pin.VISUAL)
    except (ValueError, RuntimeError) as e:
        raise InputError(
            f"Pinocchio cannot read the URDF: {e}",
            file=str(description.source),
            fix="run `footforge check` on it for the element at fault",
        ) from None

    children = {j.find("child").get("link") for j in root.findall("joint")}
    links = [e.get("name") for e in root.findall("link")]
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise InputError(
            f"the URDF has {len(roots)} root links {roots}",
            file=str(description.source),
            fix="connect every link to one tree; run `footforge check`",
        )
    link_of_joint = {j.get("name"): j.find("child").get("link") for j in root.findall("joint")}
    link_of_joint[FLOATING_JOINT] = roots[0]
    mimics = []
    for j in root.findall("joint"):
        m = j.find("mimic")
        if m is not None:
            mimics.append((j.get("name"), m.get("joint"), float(m.get("multiplier", 1.0)), float(m.get("offset", 0.0))))
    return ParsedURDF(
        description=description,
        urdf=urdf,
        model=model,
        collision=collision,
        visual=visual,
        root_link=roots[0],
        link_of_joint=link_of_joint,
        child_order={name: i for i, name in enumerate(links)},
        mimics=tuple(mimics),
    )


def is_mesh(geom_object) -> bool:
    return type(geom_object.geometry).__name__ not in ("Box", "Sphere", "Cylinder", "Capsule")


def children_in_urdf_order(parsed: ParsedURDF, joint_id: int) -> list[int]:
    kids = [j for j in range(1, parsed.model.njoints) if parsed.model.parents[j] == joint_id]
    return sorted(kids, key=lambda j: parsed.child_order[parsed.link_of(j)])
