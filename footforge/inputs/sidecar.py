"""The sidecar: what a foot's URDF cannot say (loop closures, coupling, spring, reference pose).

A sidecar is a YAML file beside the foot description, named `<stem>.sidecar.yaml` for a
description `<stem>.urdf` or `<stem>.urdf.xacro`; `--sidecar PATH` overrides it. The format is
documented field by field in descriptions/softfoot_q/urdf/softfoot_q.sidecar.yaml.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from footforge.inputs.yaml_reader import YamlReader, read_yaml

SIDECAR_FORMAT = 1


@dataclass(frozen=True)
class Closure:
    """A pin that closes a loop: `point` of `link` coincides with `to_point` of `to_link`."""

    name: str
    link: str
    point: tuple[float, float, float]
    """In `link`'s frame, m."""
    to_link: str
    to_point: tuple[float, float, float]
    """In `to_link`'s frame, m."""
    axis: tuple[float, float, float]
    """Pin axis, unit vector in `link`'s frame."""


@dataclass(frozen=True)
class Coupling:
    """Joint equality: q[joint] = multiplier * q[follows]."""

    joint: str
    follows: str
    multiplier: float


@dataclass(frozen=True)
class TendonSpring:
    """A linear spring on a weighted sum of joint angles: tau_i = -coef_i * k * (sum - rest)."""

    joints: Mapping[str, float]
    """Joint name -> coefficient in the sum."""
    stiffness: float
    """N m/rad."""
    rest: float
    """rad."""


@dataclass(frozen=True)
class JointDynamics:
    damping: float
    """Viscous damping, N m s/rad."""
    frictionloss: float
    """Dry friction, N m."""
    armature: float
    """Added rotor inertia, kg m^2 (numerical conditioning of tiny links)."""


@dataclass(frozen=True)
class Sidecar:
    source: Path
    root_link: str | None
    """Link of the foot description bolted to the robot's foot mount; None: detected
    (footforge.inputs.foot_root). Links above it (a test rig's `world`, a leg) are dropped."""
    arch_joints: tuple[str, ...]
    roll_front: str
    roll_back: str
    roll_coupling: Coupling | None
    closures: tuple[Closure, ...]
    arch_spring: TendonSpring | None
    joint_dynamics: Mapping[str, JointDynamics]
    """Family ('arch', 'roll', 'chain') -> dynamics."""
    reference_joints: Mapping[str, float] = field(default_factory=dict)
    """Joint angles of the reference (slack) pose, rad; unlisted joints are 0 or solved."""
    solve_closures: bool = True
    """Solve the chain pins of the reference pose so that every closure closes."""
    friction: float = 0.8

    @property
    def roll_joints(self) -> tuple[str, str]:
        return (self.roll_front, self.roll_back)


SHIPPED_SIDECARS = {"softfoot_thing_description": ("softfoot_q", "public_sidecar.yaml")}
"""ROS package name of a published foot description -> the sidecar footforge ships for it, under
descriptions/ (its owners cannot be asked to add ours beside their files)."""


def _enclosing_package(path: Path) -> str | None:
    """Name in the package.xml of the nearest folder above `path` that has one."""
    from footforge.inputs.description import _package_name

    for folder in Path(path).resolve().parents:
        if (folder / "package.xml").is_file():
            return _package_name(folder / "package.xml")
    return None


def find_sidecar(description: Path) -> Path:
    """The sidecar of a foot description when --sidecar is not given: `<stem>.sidecar.yaml`
    beside it if that exists, else the one footforge ships for the ROS package that holds the
    description (SHIPPED_SIDECARS), else the path beside it (whose absence load_sidecar reports)."""
    beside = default_sidecar_path(description)
    if beside.is_file():
        return beside
    shipped = SHIPPED_SIDECARS.get(_enclosing_package(description) or "")
    if shipped:
        from footforge.inputs.description import descriptions_dir

        return descriptions_dir().joinpath(*shipped)
    return beside


def default_sidecar_path(description: Path) -> Path:
    name = description.name
    for suffix in (".xacro", ".urdf"):
        if name.endswith(suffix):
            name = name[: -len(suffix)]
    return description.parent / f"{name}.sidecar.yaml"


_TOP_KEYS = {
    "format",
    "root_link",
    "arch_joints",
    "roll_joints",
    "roll_coupling",
    "closures",
    "arch_spring",
    "joint_dynamics",
    "reference_pose",
    "friction",
}
FAMILIES = ("arch", "roll", "chain")


def load_sidecar(path: str | Path) -> Sidecar:
    """Reads and validates a sidecar file.

    Raises:
      InputError: missing file, malformed YAML, unknown or missing keys, bad values.
    """
    path = Path(path)
    data = read_yaml(
        path,
        what="sidecar file",
        fix="write one (see descriptions/softfoot_q/urdf/softfoot_q.sidecar.yaml) or pass --sidecar PATH",
    )
    top = YamlReader(data, "", path)
    top.check_keys(_TOP_KEYS)
    fmt = top.get("format").data
    if fmt != SIDECAR_FORMAT:
        raise top.get("format").fail(f"unsupported format {fmt!r}", f"set format: {SIDECAR_FORMAT}")

    roll = top.get("roll_joints")
    roll.check_keys({"front", "back"})
    coupling = None
    if top.mapping().get("roll_coupling") is not None:
        c = top.get("roll_coupling")
        c.check_keys({"joint", "follows", "multiplier"})
        coupling = Coupling(c.get("joint").str(), c.get("follows").str(), c.get("multiplier").float())

    closures = []
    cl = top.get("closures")
    if not isinstance(cl.data, list) or not cl.data:
        raise cl.fail("expected a non-empty list of closures", "list each loop-closing pin")
    for i, item in enumerate(cl.data):
        r = YamlReader(item, f"closures[{i}]", path)
        r.check_keys({"name", "link", "point", "to_link", "to_point", "axis"})
        axis = r.get("axis").vec3()
        norm = math.sqrt(sum(a * a for a in axis))
        if norm < 1e-9:
            raise r.get("axis").fail("zero pin axis", "give a unit vector such as [1, 0, 0]")
        closures.append(
            Closure(
                name=r.get("name").str(),
                link=r.get("link").str(),
                point=r.get("point").vec3(),
                to_link=r.get("to_link").str(),
                to_point=r.get("to_point").vec3(),
                axis=(axis[0] / norm, axis[1] / norm, axis[2] / norm),
            )
        )

    spring = None
    if top.mapping().get("arch_spring") is not None:
        s = top.get("arch_spring")
        s.check_keys({"joints", "stiffness", "rest"})
        spring = TendonSpring(
            joints=s.get("joints").float_map(),
            stiffness=s.get("stiffness").float(min_value=0.0),
            rest=s.get("rest", 0.0).float(),
        )

    dyn = {}
    jd = top.get("joint_dynamics", {}).check_keys(set(FAMILIES))
    for fam in FAMILIES:
        f = jd.get(fam, {"damping": 0.0, "frictionloss": 0.0, "armature": 0.0})
        f.check_keys({"damping", "frictionloss", "armature"})
        dyn[fam] = JointDynamics(
            damping=f.get("damping", 0.0).float(min_value=0.0),
            frictionloss=f.get("frictionloss", 0.0).float(min_value=0.0),
            armature=f.get("armature", 0.0).float(min_value=0.0),
        )

    ref = top.get("reference_pose", {"joints": {}, "solve_closures": True})
    ref.check_keys({"joints", "solve_closures"})
    return Sidecar(
        source=path.resolve(),
        root_link=top.get("root_link").str() if top.mapping().get("root_link") is not None else None,
        arch_joints=top.get("arch_joints").str_list(),
        roll_front=roll.get("front").str(),
        roll_back=roll.get("back").str(),
        roll_coupling=coupling,
        closures=tuple(closures),
        arch_spring=spring,
        joint_dynamics=dyn,
        reference_joints=ref.get("joints", {}).float_map(),
        solve_closures=ref.get("solve_closures", True).bool(),
        friction=top.get("friction", 0.8).float(min_value=0.0),
    )
