"""Foot models for each variant, authored with dm_control.mjcf from a parsed foot description.

- `full`: the closed chain as described: one body per link, the sidecar's loop closures as
  site-to-site `connect` equalities (a pin = point coincidence; the pin axis is implied by the
  parallel chain pins), the roll coupling as a joint equality, the arch band as a fixed tendon
  spring. Its keyframe pose is the sidecar's slack reference pose.
- `aff`, `aof`: the bodies of footforge.models.derivation (which links each replaces, its hinge,
  its composite mass properties at the reference pose), with the replaced links' visual meshes.
What collides is the parameter file's `collision` (params.FootContact), two independent choices:
each sole body collides through the box that encloses the replaced links' collision geometry at
the reference pose, or through spheres or capsules on that box's bottom face (what MJX collides
cheapest with heightfields); and the parts above the sole (the ankle's own geometry, one box per
arch and roll link) collide too, or not (shipped: the sole box alone).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin
from dm_control import mjcf

from footforge.errors import InputError
from footforge.geometry import box_corners, sole_primitives as geometry_sole_primitives
from footforge.inputs.params import FootContact, PassiveJoint
from footforge.inputs.sidecar import FAMILIES, Sidecar
from footforge.mjcf.elements import MeshAssets, add_body_tree, add_default_classes, add_geoms, inertial_attributes
from footforge.mjcf.writing import compile_model
from footforge.models.derivation import DerivedBody, aof_sole_halves, derived_bodies
from footforge.models.foot_source import FootSource
from footforge.models.urdf import quat_wxyz
from footforge.variants import foot_variant

DERIVED_JOINT_CLASS = "foot_passive"


@dataclass
class FootModel:
    """One foot, ready to attach at a robot's foot mount (its root body has no joint)."""

    variant: str
    mjcf: mjcf.RootElement
    root_body: str
    reference_qpos: dict[str, float]
    """Joint name -> angle of the reference pose (all zero for derived feet), rad."""
    passive_joints: list[str]
    touchdown: np.ndarray
    """Lowest point of the foot's collision geometry below the ankle at the reference pose, in the
    root body frame, m."""
    info: dict = field(default_factory=dict)
    """Figures for the build report."""


def _new_root(name: str, sidecar: Sidecar, contact_solref) -> mjcf.RootElement:
    root = mjcf.RootElement(model=name)
    # MJCF's default unit for angles is the degree: a foot compiled on its own (compile_model)
    # would otherwise read the joint ranges in radians as degrees (30 deg became 0.5 deg).
    root.compiler.angle = "radian"
    add_default_classes(root, friction=sidecar.friction, contact_solref=contact_solref)
    return root


def _hull_geoms(source: FootSource, assets: MeshAssets) -> dict[str, list[dict]]:
    geoms = {}
    for name, hulls in source.hulls.items():
        stem = name.rsplit("_", 1)[0]
        geoms[name] = [
            dict(type="mesh", mesh=assets.from_bytes(f"{stem}_hull{i}", hulls.stl_bytes(i)))
            for i in range(len(hulls.vertices))
        ]
    return geoms


def _root_body(source: FootSource, root: mjcf.RootElement, assets: MeshAssets, hull_geoms, *, collide: bool = True):
    parsed = source.parsed
    body = root.worldbody.add("body", name=parsed.root_link)
    body.add("inertial", **inertial_attributes(parsed.model.inertias[1]))
    add_geoms(
        body, parsed, 1, assets, collision_geoms=hull_geoms, kinds=("visual", "collision") if collide else ("visual",)
    )
    return body


def build_full(source: FootSource, *, name: str = "foot") -> FootModel:
    parsed, sidecar = source.parsed, source.sidecar
    root = _new_root(name, sidecar, source.params.contact_solref_for("full"))
    full = source.params.full
    for fam in FAMILIES:
        d = sidecar.joint_dynamics[fam]
        # The ranges are the foot's mechanical stops, as stiff as the pins that close its loops.
        # MuJoCo scales a limit's stiffness by the joint's effective inertia (k ~ I / timeconst^2):
        # for these 8-26 g links its default stops were so soft that a walking robot's arches passed
        # them by up to 100 deg and the simulation diverged (benchmarks/RESULTS.md, "The shipped
        # policies on the 34-joint closed chain"). The drop tests barely reach them.
        root.default.add("default", dclass=fam).joint.set_attributes(
            damping=d.damping, frictionloss=d.frictionloss, armature=d.armature, solreflimit=list(full.closure_solref)
        )
    assets = MeshAssets(root)
    hull_geoms = _hull_geoms(source, assets)
    families = source.families
    q = source.reference.q
    reference = {parsed.model.names[j]: float(q[parsed.model.joints[j].idx_q]) for j in families}
    # Authored at the slack reference pose (joint `ref`): qpos0 satisfies the loop closures, so a
    # model opened in a viewer starts consistent rather than snapping its chains shut.
    bodies = add_body_tree(
        parsed,
        _root_body(source, root, assets, hull_geoms),
        assets,
        joint_class=lambda j: families[j] if families[j] in FAMILIES else None,
        collision_geoms=hull_geoms,
        reference=reference,
    )
    for c in sidecar.closures:
        sites = []
        for link, point, tag in ((c.link, c.point, "a"), (c.to_link, c.to_point, "b")):
            joint_id, placement = parsed.body_of_link(link)
            sites.append(
                bodies[joint_id].add(
                    "site",
                    name=f"closure_{c.name}_{tag}",
                    group=4,
                    size=[0.001],
                    pos=placement.act(np.asarray(point, float)),
                )
            )
        root.equality.add(
            "connect",
            name=f"closure_{c.name}",
            site1=sites[0],
            site2=sites[1],
            solref=list(full.closure_solref),
            solimp=list(full.closure_solimp),
        )
    couplings = list(parsed.mimics)
    if sidecar.roll_coupling:
        rc = sidecar.roll_coupling
        couplings.append((rc.joint, rc.follows, rc.multiplier, 0.0))
    for joint, follows, mult, offset in couplings:
        # MuJoCo's joint equality couples offsets from qpos0: y - y0 = a0 + a1 (x - x0). With the
        # bodies authored at the reference pose (y0, x0 its angles), joint = offset + mult * follows
        # needs a0 = offset + mult * x0 - y0.
        a0 = offset + mult * reference.get(follows, 0.0) - reference.get(joint, 0.0)
        root.equality.add(
            "joint",
            name=f"couple_{joint}",
            joint1=joint,
            joint2=follows,
            polycoef=[a0, mult, 0, 0, 0],
            solref=list(full.closure_solref),
            solimp=list(full.closure_solimp),
        )
    if sidecar.arch_spring:
        s = sidecar.arch_spring
        tendon = root.tendon.add("fixed", name="arch_spring", stiffness=s.stiffness, springlength=[s.rest, s.rest])
        for joint, coef in s.joints.items():
            parsed.joint_id(joint)  # names an unknown joint clearly
            tendon.add("joint", joint=joint, coef=coef)

    info = {
        "closure_error_at_reference_m": source.reference.closure_error_m,
        "chain_sag_at_reference_m": source.reference.chain_sag_m,
        "closures": len(sidecar.closures),
        "couplings": len(couplings),
    }
    return _finish(FootModel("full", root, parsed.root_link, reference, list(reference), np.zeros(3), info))


def posed_at_reference(foot: FootModel) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The foot compiled by MuJoCo, its kinematics at the reference pose."""
    model = compile_model(foot.mjcf)
    data = mujoco.MjData(model)
    for joint, value in foot.reference_qpos.items():
        data.qpos[model.jnt_qposadr[model.joint(joint).id]] = value
    mujoco.mj_kinematics(model, data)
    return model, data


def geom_points(model: mujoco.MjModel, data: mujoco.MjData, geom_id: int) -> np.ndarray:
    """World-frame points whose convex hull contains the geom (mesh vertices, box corners, or the
    corners of the geom's bounding box for other shapes)."""
    R, p = data.geom_xmat[geom_id].reshape(3, 3), data.geom_xpos[geom_id]
    if model.geom_type[geom_id] == mujoco.mjtGeom.mjGEOM_MESH:
        m = model.geom_dataid[geom_id]
        local = model.mesh_vert[model.mesh_vertadr[m] : model.mesh_vertadr[m] + model.mesh_vertnum[m]]
    else:
        half = (
            model.geom_size[geom_id]
            if model.geom_type[geom_id] == mujoco.mjtGeom.mjGEOM_BOX
            else model.geom_aabb[geom_id, 3:]
        )
        center = 0 if model.geom_type[geom_id] == mujoco.mjtGeom.mjGEOM_BOX else model.geom_aabb[geom_id, :3]
        local = box_corners(half, center)
    return local @ R.T + p


def collision_points(model, data, body_names) -> np.ndarray:
    ids = {model.body(b).id for b in body_names}
    pts = [
        geom_points(model, data, g)
        for g in range(model.ngeom)
        if model.geom_bodyid[g] in ids and model.geom_group[g] == 3
    ]
    return np.concatenate(pts) if pts else np.zeros((0, 3))


def build_derived(source: FootSource, variant: str, *, name: str = "foot", full: FootModel | None = None) -> FootModel:
    """AFF or AOF as MJCF: the bodies of footforge.models.derivation, each with its hinge (the
    parameter file's spring, damper and armature), the replaced links' visual meshes and its
    colliders (the module docstring says which).

    `full` is the closed-chain foot of `source` when the caller already built it.
    """
    parsed, params = source.parsed, source.params
    joints = params.joints_for(variant)
    contact = params.foot_contact[variant]
    bodies = derived_bodies(source, variant)
    reference = posed_at_reference(full or build_full(source, name="reference"))
    data = parsed.model.createData()
    pin.forwardKinematics(parsed.model, data, source.reference.q)

    root = _new_root(name, source.sidecar, params.contact_solref_for(variant))
    root.default.add("default", dclass=DERIVED_JOINT_CLASS).joint.set_attributes(type="hinge", limited="true")
    assets = MeshAssets(root)
    elements: dict[str | None, Any] = {
        None: _root_body(source, root, assets, _hull_geoms(source, assets), collide=contact.upper_collisions)
    }
    frames: dict[str | None, Any] = {None: pin.SE3.Identity()}
    for b in bodies:
        rel = frames[b.parent].actInv(b.frame)
        body = elements[b.parent].add("body", name=b.name, pos=np.array(rel.translation), quat=quat_wxyz(rel.rotation))
        body.add("inertial", **inertial_attributes(b.inertia))
        j: PassiveJoint = joints[b.joint]
        body.add(
            "joint",
            name=b.joint,
            dclass=DERIVED_JOINT_CLASS,
            axis=b.frame.rotation.T @ b.axis,
            range=list(b.range_rad),
            stiffness=j.stiffness,
            damping=j.damping,
            armature=j.armature,
            springref=j.springref,
        )
        for member in b.members:  # the replaced links' looks
            add_geoms(body, parsed, member, assets, offset=b.frame.actInv(data.oMi[member]), kinds=("visual",))
        _add_envelope_colliders(body, b, source, variant, reference)
        elements[b.name], frames[b.name] = body, b.frame
    sole_lift = params.sole_lift_m[variant]
    clearance = sole_clearance(root)
    if clearance < 0.001:  # inf when only the sole collides
        raise InputError(
            f"sole_lift_m {sole_lift:g} m raises the {variant} sole to within 1 mm of the foot's other "
            f"collision boxes (clearance {clearance * 1e3:.1f} mm)",
            file=str(params.source),
            element=f"{variant}.sole_lift_m",
            fix=f"keep sole_lift_m below {sole_lift + clearance - 0.001:.4f} m so the sole stays the lowest part",
        )
    names = [b.joint for b in bodies]
    split = aof_sole_halves(source) if foot_variant(variant).split_sole else {}
    info = {
        "replaced_links": {k: [parsed.link_of(j) for j in v] for k, v in split.items()},
        "sole_clearance_m": clearance if np.isfinite(clearance) else None,
        "contact": {
            "sole": contact.sole,
            "upper_collisions": contact.upper_collisions,
            **({"grid": list(contact.grid), "radius_m": contact.radius_m} if contact.sole != "box" else {}),
        },
        "reference_pose_closure_error_m": source.reference.closure_error_m,
    }
    return _finish(FootModel(variant, root, parsed.root_link, {n: 0.0 for n in names}, names, np.zeros(3), info))


def _add_envelope_colliders(body, derived: DerivedBody, source: FootSource, variant: str, reference) -> None:
    """The colliders of one derived body: per envelope, the box that encloses its links' collision
    geometry at the reference pose (the sole's raised by sole_lift_m), or for the sole the spheres
    or capsules on that box's bottom face (the parameter file's `collision`); the envelopes above
    the sole only where `collision.upper_collisions`."""
    parsed, params = source.parsed, source.params
    contact = params.foot_contact[variant]
    ref_model, ref_data = reference
    frame = derived.frame
    for group_name, group in derived.envelopes:
        is_sole = group_name.startswith("sole")
        if not (is_sole or contact.upper_collisions):
            continue
        pts = collision_points(ref_model, ref_data, [parsed.link_of(m) for m in group])
        if len(pts) == 0:
            continue
        local = (pts - frame.translation) @ frame.rotation
        lo, hi = local.min(0), local.max(0)
        center, half = (lo + hi) / 2 + [0.0, 0.0, params.sole_lift_m[variant] if is_sole else 0.0], (hi - lo) / 2
        if is_sole and contact.sole != "box":
            if contact.radius_m > min(half[:2]):
                raise InputError(
                    f"radius_m {contact.radius_m:g} m is wider than the {variant} {group_name} "
                    f"plate (half sizes {half[0]:.4f} x {half[1]:.4f} m)",
                    file=str(params.source),
                    element=f"{variant}.collision.radius_m",
                    fix=f"give at most {min(half[:2]):.4f} m",
                )
            for i, shape in enumerate(sole_primitives(center, half, contact)):
                body.add("geom", name=f"{group_name}_{i}_collision", dclass="collision", **shape)
        else:
            body.add("geom", name=f"{group_name}_collision", dclass="collision", type="box", pos=center, size=half)


def sole_primitives(center, half, contact: FootContact) -> list[dict]:
    """Geom attributes of the spheres or capsules (FootContact) standing in for a sole box
    (footforge.geometry.sole_primitives)."""
    return geometry_sole_primitives(center, half, contact.sole, contact.grid, contact.radius_m)


def sole_clearance(root: mjcf.RootElement) -> float:
    """How far the lowest collision point of the foot's other bodies lies above the sole's, at
    the reference pose (m): the most a sole lift can add before the sole stops being the part
    that touches the ground; inf when only the sole collides."""
    model = compile_model(root)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    lowest = {True: np.inf, False: np.inf}
    for g in range(model.ngeom):
        if model.geom_group[g] == 3:
            is_sole = model.geom(g).name.startswith("sole")
            lowest[is_sole] = min(lowest[is_sole], geom_points(model, data, g)[:, 2].min())
    return float(lowest[False] - lowest[True])


def sole_bodies(foot: FootModel) -> list[str]:
    """Names of the bodies whose bottoms form the sole: the closed chain's links (the bodies of its
    `chain` joint family, whatever the description calls them), or a derived foot's sole plates."""
    if foot_variant(foot.variant).closed_chain:
        return [j.parent.name for j in foot.mjcf.find_all("joint") if j.dclass == "chain"]
    return [b.name for b in foot.mjcf.find_all("body") if b.name.startswith("sole")]  # footforge's own names


def _finish(foot: FootModel) -> FootModel:
    """Measures the touchdown point: the lowest collision point under the ankle, reference pose."""
    model, data = posed_at_reference(foot)
    pts = collision_points(model, data, [model.body(b).name for b in range(1, model.nbody)])
    foot.touchdown = np.array([0.0, 0.0, pts[:, 2].min()])
    foot.mjcf.find("body", foot.root_body).add("site", name="touchdown", pos=foot.touchdown, size=[0.005], group=4)
    return foot


def clone(foot: FootModel, name: str) -> FootModel:
    """A copy of `foot` under another model name (for attaching one per leg)."""
    c = copy.copy(foot)
    c.mjcf = copy.deepcopy(foot.mjcf)
    c.mjcf.model = name
    return c
