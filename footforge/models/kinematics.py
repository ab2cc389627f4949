"""Kinematics of a closed-chain foot with Pinocchio: families, closures, reference pose, composites.

All poses are configurations of the foot's Pinocchio model (parsed with a free-flyer root at the
identity, so world = the foot's root link frame = the robot's foot mount frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.optimize import least_squares

from footforge.errors import CheckFailure, InputError
from footforge.inputs.sidecar import Closure, Sidecar
from footforge.models.urdf import ParsedURDF, joint_axis

CLOSURE_TOLERANCE_M = 1e-9
"""A solved reference pose must close every loop to this distance."""


def descendants(parsed: ParsedURDF, joint_id: int) -> list[int]:
    """Joint ids in the subtree of `joint_id`, itself excluded."""
    return [j for j in parsed.model.subtrees[joint_id] if j != joint_id]


def joint_families(parsed: ParsedURDF, sidecar: Sidecar) -> dict[int, str]:
    """Family of every moving joint below the root: arch, roll, chain (below a roll joint) or
    other (e.g. a massless mimic driver)."""
    arch = {parsed.joint_id(n) for n in sidecar.arch_joints}
    roll = {parsed.joint_id(n) for n in sidecar.roll_joints}
    chain = {d for r in roll for d in descendants(parsed, r)}
    families = {}
    for j in range(2, parsed.model.njoints):  # 0 universe, 1 root free-flyer
        families[j] = "arch" if j in arch else "roll" if j in roll else "chain" if j in chain else "other"
    return families


def chain_of(parsed: ParsedURDF, sidecar: Sidecar, closure: Closure) -> list[int]:
    """Joint ids from the first pin of the closure's chain down to its last, in order."""
    joint_id, _ = parsed.body_of_link(closure.link)
    roll = {parsed.joint_id(n) for n in sidecar.roll_joints}
    chain = []
    while joint_id not in roll:
        if joint_id <= 1:
            raise InputError(
                f"closure '{closure.name}': link '{closure.link}' is not below a roll joint",
                file=str(sidecar.source),
                element=f"closure '{closure.name}'",
                fix="closures must start on a chain that hangs from a roll link",
            )
        chain.append(joint_id)
        joint_id = parsed.model.parents[joint_id]
    return chain[::-1]


def point_in_root(parsed: ParsedURDF, data: pin.Data, link: str, point) -> np.ndarray:
    joint_id, placement = parsed.body_of_link(link)
    return data.oMi[joint_id].act(placement.act(np.asarray(point, dtype=float)))


def closure_residuals(parsed: ParsedURDF, sidecar: Sidecar, q: np.ndarray) -> np.ndarray:
    """(n_closures, 3) gap between each closure's two points in the root frame, m."""
    data = parsed.model.createData()
    pin.forwardKinematics(parsed.model, data, q)
    return np.array(
        [
            point_in_root(parsed, data, c.link, c.point) - point_in_root(parsed, data, c.to_link, c.to_point)
            for c in sidecar.closures
        ]
    )


CLOSURE_AXIS_TOL_RAD = 0.0175
"""A closure's pin axis may differ from its chain's pins by this (1 degree): footforge closes a loop
with a point coincidence (a `connect` equality), which leaves the rotation about the pin to the
chain's own parallel pins; a closure whose axis is not theirs would need a hinge the model lacks."""


def closure_axis_errors_rad(parsed: ParsedURDF, sidecar: Sidecar, q: np.ndarray) -> np.ndarray:
    """Per closure, the angle between its pin axis (the sidecar's, in `link`'s frame) and the axis
    of the pin that carries `link` in its chain, at configuration q, rad."""
    data = parsed.model.createData()
    pin.forwardKinematics(parsed.model, data, q)
    angles = []
    for c in sidecar.closures:
        joint_id, placement = parsed.body_of_link(c.link)
        closure_axis = data.oMi[joint_id].rotation @ placement.rotation @ np.asarray(c.axis, dtype=float)
        pin_axis = data.oMi[joint_id].rotation @ joint_axis(parsed.model.joints[joint_id])
        angles.append(float(np.arccos(np.clip(abs(closure_axis @ pin_axis), 0.0, 1.0))))
    return np.array(angles)


def closure_axis_problems(parsed: ParsedURDF, sidecar: Sidecar, q: np.ndarray) -> list[tuple[str, str, str]]:
    """(element, message, fix) of every closure whose pin axis is more than CLOSURE_AXIS_TOL_RAD
    off its chain's pins at configuration q."""
    problems = []
    for c, angle in zip(sidecar.closures, closure_axis_errors_rad(parsed, sidecar, q)):
        if angle > CLOSURE_AXIS_TOL_RAD:
            problems.append(
                (
                    f"closure '{c.name}'",
                    f"its pin axis {list(c.axis)} (in {c.link}'s frame) is {np.degrees(angle):.1f} deg off "
                    "the axis of the "
                    f"pin that carries {c.link}; footforge closes loops with a point coincidence and relies on the "
                    "chain's parallel pins for the rotation",
                    f"give the axis of the chain's pins in {c.link}'s frame (closures, axis) in {sidecar.source}",
                )
            )
    return problems


def set_joint(parsed: ParsedURDF, q: np.ndarray, name: str, value: float) -> None:
    q[parsed.model.joints[parsed.joint_id(name)].idx_q] = value


def get_joint(parsed: ParsedURDF, q: np.ndarray, name: str) -> float:
    return float(q[parsed.model.joints[parsed.joint_id(name)].idx_q])


@dataclass(frozen=True)
class ReferencePose:
    q: np.ndarray
    """Pinocchio configuration of the foot (root at the identity)."""
    closure_error_m: float
    """Largest closure gap at this pose."""
    chain_sag_m: float
    """How far the lowest chain pin hangs below the chain's end pins."""


def reference_pose(parsed: ParsedURDF, sidecar: Sidecar) -> ReferencePose:
    """The sidecar's slack pose; with solve_closures, chain pins solved so the loops close.

    Each chain's unlisted pins are solved for the closest-to-circular-arc shape that closes its
    loop (least squares with a smoothness term, then Gauss-Newton on the gap alone), sagging
    downward (the lower of the two mirror solutions).

    Raises:
      CheckFailure: a loop cannot be closed at this pose (to CLOSURE_TOLERANCE_M).
    """
    model = parsed.model
    q = pin.neutral(model)
    for name, value in sidecar.reference_joints.items():
        set_joint(parsed, q, name, value)
    if sidecar.roll_coupling:
        c = sidecar.roll_coupling
        set_joint(parsed, q, c.joint, c.multiplier * get_joint(parsed, q, c.follows))
    listed = {parsed.joint_id(n) for n in sidecar.reference_joints}
    if sidecar.solve_closures:
        for closure in sidecar.closures:
            chain = [j for j in chain_of(parsed, sidecar, closure) if j not in listed]
            q = _solve_chain(parsed, sidecar, closure, chain, q)
    gaps = np.linalg.norm(closure_residuals(parsed, sidecar, q), axis=1)
    worst = int(np.argmax(gaps))
    if gaps[worst] > CLOSURE_TOLERANCE_M:
        closure = sidecar.closures[worst]
        raise CheckFailure(
            f"closure '{closure.name}' does not close at the reference pose: gap {gaps[worst] * 1e3:.3f} mm "
            f"between '{closure.link}' {list(closure.point)} and '{closure.to_link}' {list(closure.to_point)}",
            file=str(sidecar.source),
            element=f"closure '{closure.name}'",
            fix="check the closure points against the description (a sign of y, a frame), or the "
            "reference_pose joints (the chain must be slack enough to reach)",
        )
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    sag = 0.0
    for closure in sidecar.closures:
        chain = chain_of(parsed, sidecar, closure)
        z = [data.oMi[j].translation[2] for j in chain]
        sag = max(sag, min(z[0], z[-1]) - min(z))
    return ReferencePose(q=q, closure_error_m=float(gaps.max()), chain_sag_m=float(sag))


def _solve_chain(parsed, sidecar, closure, chain, q0):
    model = parsed.model
    idx = [model.joints[j].idx_q for j in chain]
    lo, hi = model.lowerPositionLimit[idx], model.upperPositionLimit[idx]
    data = model.createData()

    def gap(x):
        q = q0.copy()
        q[idx] = x
        pin.forwardKinematics(model, data, q)
        return point_in_root(parsed, data, closure.link, closure.point) - point_in_root(
            parsed, data, closure.to_link, closure.to_point
        )

    def smooth(x, weight):
        return np.concatenate([gap(x), weight * np.diff(x[1:])])

    best = None
    for sign in (1.0, -1.0):
        # Start bent: first pin +-0.3 rad, the rest spread evenly so the tip comes back level.
        x0 = np.full(len(idx), -sign * 0.6 / max(len(idx) - 1, 1))
        x0[0] = sign * 0.3
        x0 = np.clip(x0, lo + 1e-6, hi - 1e-6)
        fit = least_squares(smooth, x0, args=(1e-3,), bounds=(lo, hi), xtol=1e-15, ftol=1e-15)
        x = fit.x
        for _ in range(50):  # Gauss-Newton on the gap alone, minimum-norm steps
            r = gap(x)
            if np.linalg.norm(r) < 1e-13:
                break
            J = np.empty((3, len(x)))
            for k in range(len(x)):
                dx = np.zeros(len(x))
                dx[k] = 1e-7
                J[:, k] = (gap(x + dx) - r) / 1e-7
            x = x - np.linalg.lstsq(J, r, rcond=None)[0]
        q = q0.copy()
        q[idx] = x
        pin.forwardKinematics(model, data, q)
        lowest = min(data.oMi[j].translation[2] for j in chain)
        if np.linalg.norm(gap(x)) < 1e-9 and np.all(x >= lo - 1e-9) and np.all(x <= hi + 1e-9):
            if best is None or lowest < best[0]:
                best = (lowest, q)
    if best is None:
        return q0  # unsolvable: reported by the caller with the measured gap
    return best[1]


def composite_inertia(parsed: ParsedURDF, joint_ids, q: np.ndarray, frame: pin.SE3) -> pin.Inertia:
    """Spatial inertia of the bodies of `joint_ids` at pose `q`, expressed in `frame` (given in
    the root frame): a sum of `pin.Inertia`, exact rigid-body algebra."""
    data = parsed.model.createData()
    pin.forwardKinematics(parsed.model, data, q)
    total = pin.Inertia.Zero()
    for j in joint_ids:
        total += data.oMi[j].act(parsed.model.inertias[j])
    return frame.actInv(total)
