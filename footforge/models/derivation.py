"""AFF and AOF derived from the closed chain at its reference pose: which links each new body
replaces, where its hinge sits and turns, and its mass properties (footforge.mjcf.foot authors
them as MJCF).

- AFF: the arches -> one `pitch` body on the ankle-pitch hinge (at the arch pivot, on the arch
  joints' common axis); the roll links and every chain link -> one rigid `sole` body on the
  ankle-roll hinge (through the two roll pivots).
- AOF: as AFF, but the roll links -> a `roll` body, and the chain links split by their centre of
  mass's x (the parameter file's split_x) into `sole_front` and `sole_back`, each on a hinge about
  its roll link's transversal (y) axis at its pivot.
Each body's mass, centre of mass and inertia are the composite (Pinocchio's inertia algebra) of
the links it replaces at the reference pose, so the derived foot at q = 0 has exactly the closed
chain's mass distribution there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from footforge.models import kinematics
from footforge.models.foot_source import FootSource
from footforge.models.urdf import ParsedURDF, joint_axis
from footforge.variants import foot_variant


@dataclass(frozen=True)
class DerivedBody:
    """One body of a derived foot, at the reference pose, in the foot's root frame."""

    name: str
    parent: str | None
    """The parent derived body; None: the foot's root body."""
    frame: pin.SE3
    """The body's frame (axes of the root frame, origin at its hinge), m."""
    members: tuple[int, ...]
    """Pinocchio joint ids of the closed chain's links it replaces."""
    joint: str
    """Its hinge's name (the parameter file's passive joint)."""
    axis: np.ndarray
    """The hinge axis in the root frame, unit."""
    range_rad: tuple[float, float]
    inertia: pin.Inertia
    """Composite mass properties of `members`, in `frame`."""
    envelopes: tuple[tuple[str, tuple[int, ...]], ...]
    """(collider name, member links) of each box that encloses part of its collision geometry:
    one per arch or roll link, and the sole's (names starting with "sole")."""


def derived_bodies(source: FootSource, variant: str) -> list[DerivedBody]:
    """The bodies of `variant` ("aff" or "aof"), parents before children."""
    parsed, sidecar, params = source.parsed, source.sidecar, source.params
    q = source.reference.q
    data = parsed.model.createData()
    pin.forwardKinematics(parsed.model, data, q)
    oMi = data.oMi
    families = source.families
    arch = [parsed.joint_id(n) for n in sidecar.arch_joints]
    front, back = parsed.joint_id(sidecar.roll_front), parsed.joint_id(sidecar.roll_back)
    chain = [j for j, f in families.items() if f == "chain"]
    other = [j for j, f in families.items() if f == "other"]

    def body(name, parent, origin, members, joint, axis, limit, envelopes) -> DerivedBody:
        frame = pin.SE3(np.eye(3), np.asarray(origin, dtype=float))
        return DerivedBody(
            name,
            parent,
            frame,
            tuple(members),
            joint,
            np.asarray(axis, dtype=float),
            limit,
            kinematics.composite_inertia(parsed, members, q, frame),
            tuple((n, tuple(m)) for n, m in envelopes),
        )

    pitch_axis = oMi[arch[0]].rotation @ joint_axis(parsed.model.joints[arch[0]])
    front_pivot, back_pivot = oMi[front].translation, oMi[back].translation
    roll_axis = (front_pivot - back_pivot) / np.linalg.norm(front_pivot - back_pivot)
    roll_origin = (front_pivot + back_pivot) / 2
    roll_envelopes = [(parsed.link_of(r), [r]) for r in (front, back)]
    bodies = [
        body(
            "pitch",
            None,
            oMi[arch[0]].translation,
            arch + other,
            "ankle_pitch",
            pitch_axis,
            joint_range(parsed, arch[0]),
            [(parsed.link_of(a), [a]) for a in arch],
        )
    ]
    if not foot_variant(variant).split_sole:  # AFF: one sole plate
        bodies.append(
            body(
                "sole",
                "pitch",
                roll_origin,
                [front, back] + chain,
                "ankle_roll",
                roll_axis,
                joint_range(parsed, front),
                roll_envelopes + [("sole", chain)],
            )
        )
        return bodies
    bodies.append(
        body(
            "roll",
            "pitch",
            roll_origin,
            [front, back],
            "ankle_roll",
            roll_axis,
            joint_range(parsed, front),
            roll_envelopes,
        )
    )
    for name, members in aof_sole_halves(source).items():
        pivot = front if name == "sole_front" else back
        bodies.append(
            body(
                name,
                "roll",
                oMi[pivot].translation,
                members,
                name,
                oMi[pivot].rotation[:, 1],  # the roll link's transversal axis
                params.aof_sole_range,
                [(name, members)],
            )
        )
    return bodies


def aof_sole_halves(source: FootSource) -> dict[str, list[int]]:
    """AOF's sole halves: the chain links whose centre of mass lies ahead of the parameter file's
    split_x (sole_front) or not (sole_back), at the reference pose."""
    parsed = source.parsed
    data = parsed.model.createData()
    pin.forwardKinematics(parsed.model, data, source.reference.q)
    chain = [j for j, f in source.families.items() if f == "chain"]
    com_x = {j: data.oMi[j].act(parsed.model.inertias[j]).lever[0] for j in chain}
    split_x = source.params.aof_split_x
    return {
        "sole_front": [j for j in chain if com_x[j] > split_x],
        "sole_back": [j for j in chain if com_x[j] <= split_x],
    }


def joint_range(parsed: ParsedURDF, joint_id: int) -> tuple[float, float]:
    """The description's limits of a joint, rad."""
    idx = parsed.model.joints[joint_id].idx_q
    return float(parsed.model.lowerPositionLimit[idx]), float(parsed.model.upperPositionLimit[idx])
