"""MJCF elements authored with dm_control.mjcf from a Pinocchio parse: default classes, bodies,
joints, geoms and mesh assets, one body per Pinocchio joint, numbers at full double precision.

MJCF conventions of the written models:
- Default classes: `visual` (group 2, no contacts, no mass), `collision` (group 3) and one class
  per joint family (set by the callers).
- The robot does not collide with itself: collision geoms have contype 0 and conaffinity 1, so
  they touch any environment geom with contype 1 (MuJoCo's default), never each other.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from dm_control import mjcf

from footforge.errors import InputError
from footforge.models.urdf import ParsedURDF, children_in_urdf_order, joint_axis, joint_kind, quat_wxyz

CONTACT_SOLMIX = 1000.0
"""MuJoCo averages two geoms' solref weighted by solmix: the robot's collision geoms outweigh a
ground geom's default 1, so the sole pad's contact stiffness holds on any terrain."""


def add_default_classes(
    root: mjcf.RootElement,
    *,
    friction: float,
    contact_solref: tuple[float, float],
    contact_solimp: tuple[float, float, float] | None = None,
) -> None:
    """The visual and collision classes every footforge model uses."""
    visual = root.default.add("default", dclass="visual")
    visual.geom.set_attributes(group=2, contype=0, conaffinity=0, density=0, mass=0)
    collision = root.default.add("default", dclass="collision")
    collision.geom.set_attributes(
        group=3,
        contype=0,
        conaffinity=1,
        friction=[friction, 0.005, 0.0001],
        solref=list(contact_solref),
        solmix=CONTACT_SOLMIX,
    )
    if contact_solimp is not None:
        collision.geom.solimp = list(contact_solimp)


def inertial_attributes(inertia: pin.Inertia) -> dict:
    I = inertia.inertia  # noqa: E741  (the inertia tensor, named as in the equations)
    return dict(
        pos=np.array(inertia.lever),
        mass=float(inertia.mass),
        fullinertia=[I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]],
    )


class MeshAssets:
    """Mesh assets of one MJCF model, one per file or per named buffer, added once."""

    def __init__(self, root: mjcf.RootElement):
        self._root = root
        self._by_key: dict[str, mjcf.Element] = {}

    def from_file(self, path: str | Path, scale=(1.0, 1.0, 1.0)) -> mjcf.Element:
        path = Path(path)
        key = f"{path}|{tuple(scale)}"
        if key not in self._by_key:
            name = self._unique(path.stem)
            asset = mjcf.Asset(contents=path.read_bytes(), extension=path.suffix.lower())
            kwargs = {} if np.allclose(scale, 1.0) else {"scale": list(scale)}
            self._by_key[key] = self._root.asset.add("mesh", name=name, file=asset, **kwargs)
        return self._by_key[key]

    def from_bytes(self, name: str, contents: bytes, extension: str = ".stl") -> mjcf.Element:
        key = f"bytes|{name}"
        if key not in self._by_key:
            self._by_key[key] = self._root.asset.add(
                "mesh", name=self._unique(name), file=mjcf.Asset(contents=contents, extension=extension)
            )
        return self._by_key[key]

    def _unique(self, stem: str) -> str:
        names = {m.name for m in self._root.asset.mesh}
        name, i = stem, 1
        while name in names:
            name, i = f"{stem}_{i}", i + 1
        return name


def geom_attributes(geom_object, assets: MeshAssets) -> dict:
    """MJCF geom attributes (type, size or mesh, pos, quat) of a Pinocchio geometry object."""
    g = geom_object.geometry
    kind = type(g).__name__
    placement = geom_object.placement
    attrs: dict[str, Any] = dict(pos=np.array(placement.translation), quat=quat_wxyz(placement.rotation))
    if kind == "Box":
        attrs.update(type="box", size=np.array(g.halfSide))
    elif kind == "Sphere":
        attrs.update(type="sphere", size=[g.radius])
    elif kind == "Cylinder":
        attrs.update(type="cylinder", size=[g.radius, g.halfLength])
    elif kind == "Capsule":
        attrs.update(type="capsule", size=[g.radius, g.halfLength])
    elif geom_object.meshPath:
        mesh = assets.from_file(geom_object.meshPath, tuple(geom_object.meshScale))
        attrs.update(type="mesh", mesh=mesh)
    else:
        raise InputError(
            f"unsupported geometry {kind} of '{geom_object.name}'", fix="use box, sphere, cylinder or mesh geometry"
        )
    return attrs


def add_joint(body: mjcf.Element, parsed: ParsedURDF, joint_id: int, *, dclass: str | None = None):
    """Adds the MJCF joint of Pinocchio joint `joint_id` (hinge or slide) to `body`."""
    model = parsed.model
    jm = model.joints[joint_id]
    name = model.names[joint_id]
    kind = joint_kind(jm)
    attrs: dict = dict(name=name, axis=joint_axis(jm))
    if dclass:
        attrs["dclass"] = dclass
    if kind == "continuous":
        attrs["type"] = "hinge"
    else:
        attrs["type"] = kind
        lo, hi = model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q]
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            attrs.update(range=[lo, hi], limited="true")
    return body.add("joint", **attrs)


def add_geoms(
    body: mjcf.Element,
    parsed: ParsedURDF,
    joint_id: int,
    assets: MeshAssets,
    *,
    collision_geoms: Mapping[str, list[dict]] | None = None,
    offset: pin.SE3 | None = None,
    kinds: tuple[str, ...] = ("visual", "collision"),
) -> None:
    """Adds the geoms of `kinds` (visual, collision) carried by `joint_id` to `body`.

    `collision_geoms` maps a Pinocchio geometry name to replacement geom attribute dicts (the
    convex hulls of a decomposed mesh); `offset` re-expresses placements in another frame.
    """
    models = {"visual": parsed.visual, "collision": parsed.collision}
    for kind in kinds:
        gmodel = models[kind]
        for go in gmodel.geometryObjects:
            if go.parentJoint != joint_id:
                continue
            placement = go.placement if offset is None else offset * go.placement
            if kind == "collision" and collision_geoms and go.name in collision_geoms:
                for i, hull in enumerate(collision_geoms[go.name]):
                    attrs = dict(hull)
                    attrs.update(pos=np.array(placement.translation), quat=quat_wxyz(placement.rotation))
                    body.add("geom", name=f"{go.name}_hull{i}", dclass="collision", **attrs)
                continue
            moved = go.copy()
            moved.placement = placement
            attrs = geom_attributes(moved, assets)
            if kind == "visual":
                attrs["rgba"] = np.array(go.meshColor)
            body.add("geom", name=f"{go.name}_{kind}", dclass=kind, **attrs)


def add_body_tree(
    parsed: ParsedURDF,
    root_body: mjcf.Element,
    assets: MeshAssets,
    *,
    joint_class,
    collision_geoms: Mapping[str, list[dict]] | None = None,
    reference: Mapping[str, float] | None = None,
) -> dict[int, mjcf.Element]:
    """Adds one MJCF body per Pinocchio joint below the root joint (id 1) under `root_body`, in
    URDF order: frame, inertial, joint (class `joint_class(joint_id)`), geoms.

    `reference` (joint name -> angle in rad, or offset in m) is the pose the model is authored in:
    each named hinge or slide gets MuJoCo's `ref` and its body is placed as at that value, so
    qpos0 is that pose while a joint's qpos keeps the description's meaning (at qpos q the body
    sits where the description puts it at q).

    Returns:
      Pinocchio joint id -> its MJCF body (the root joint maps to `root_body`).
    """
    model = parsed.model
    bodies = {1: root_body}
    reference = reference or {}

    def add_subtree(joint_id: int) -> None:
        for child in children_in_urdf_order(parsed, joint_id):
            placement = model.jointPlacements[child]
            name, kind = model.names[child], joint_kind(model.joints[child])
            ref = reference.get(name, 0.0) if kind in ("hinge", "slide") else 0.0
            if ref:
                axis = joint_axis(model.joints[child])
                motion = (
                    pin.SE3(pin.exp3(axis * ref), np.zeros(3)) if kind == "hinge" else pin.SE3(np.eye(3), axis * ref)
                )
                placement = placement * motion
            body = bodies[joint_id].add(
                "body",
                name=parsed.link_of(child),
                pos=np.array(placement.translation),
                quat=quat_wxyz(placement.rotation),
            )
            body.add("inertial", **inertial_attributes(model.inertias[child]))
            joint = add_joint(body, parsed, child, dclass=joint_class(child))
            if ref:
                joint.ref = ref
            add_geoms(body, parsed, child, assets, collision_geoms=collision_geoms)
            bodies[child] = body
            add_subtree(child)

    add_subtree(1)
    return bodies
