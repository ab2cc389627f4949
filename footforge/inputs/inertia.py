"""Physical consistency of rigid-body inertia: mass, centre of mass and the 3x3 inertia tensor.

A rigid body is a non-negative mass distribution ρ(p). Everything a dynamics engine knows of it
is ten numbers, its moments up to second order (about the frame origin):

    m = ∫ρ,   h = ∫ρ p = m c,   Σ = ∫ρ p pᵀ,   and the rotational inertia I_o = tr(Σ)·1 − Σ.

Not every (m, c, I) is the moment set of some ρ ≥ 0. The criteria, in the order they are reported:

* **mass**: m > 0 and every number finite.
* **symmetry**: I = Iᵀ (URDF stores six numbers, so only hand-built tensors can fail this).
* **positive definiteness**: every principal moment I₁, I₂, I₃ (eigenvalue of I) is > 0. A zero
  moment is a point or line mass; simulators divide by the moments (MuJoCo rejects values below
  its mjMINVAL), so footforge asks for strictly positive moments.
* **triangle inequality**: in principal axes about the COM, I₁ = ∫ρ(y² + z²) and so on, hence
  I₂ + I₃ − I₁ = 2∫ρ x² ≥ 0: each principal moment is at most the sum of the other two. Equality
  means all the mass lies in one plane. A positive definite tensor can still break this (the
  public SoftFoot-Q ankle has moments 4.50e-6, 1.88e-6, 1.05e-6 kg·m²: no body has them).
* **pseudo-inertia**: J = ∫ρ [p; 1][p; 1]ᵀ = [[Σ, h], [hᵀ, m]] is an integral of positive
  semidefinite rank-one matrices, so J ⪰ 0. Conversely every J ⪰ 0 is the moment set of some
  non-negative mass distribution (point masses allowed) [Wensing, Kim & Slotine, "Linear matrix
  inequalities for physically consistent inertial parameter identification", RA-L 2018]: J ⪰ 0
  is the *full* condition of physical realizability, and it is linear in the ten parameters.
  With m > 0 the Schur complement gives J ⪰ 0 ⇔ Σ_c = Σ − h hᵀ/m ⪰ 0, the second moment about
  the COM, whose eigenvalues are (I_j + I_k − I_i)/2; that is also how it is tested, since the
  eigenvalues of J itself are ill-conditioned when the COM is far from the frame origin. So in
  exact arithmetic J ⪰ 0 holds exactly when the triangle inequality holds (which implies
  moments ≥ 0, since I_i = σ_j + σ_k); the stricter "moments > 0" is a simulator requirement,
  not a physical one. Both are reported independently so that a caller sees each criterion
  that fails; the test suite cross-checks the equivalence on random tensors and builds each
  physical body from six point masses.

`balance_inertia` repairs a tensor that fails: it keeps the principal axes and changes only the
principal moments, the least it can (see its docstring).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

DEFAULT_RTOL = 1e-9
"""Relative tolerance of the symmetry, triangle and pseudo-inertia tests."""

EIGEN_FLOOR_REL = 1e-12
"""`balance_inertia` raises principal moments to at least this fraction of the largest one..."""
EIGEN_FLOOR_ABS = 1e-12
"""...and to at least this many kg·m² (above MuJoCo's mjMINVAL = 1e-15)."""
TRIANGLE_MARGIN_REL = 1e-6
"""`balance_inertia` leaves the triangle inequality satisfied by this fraction of the largest
principal moment (robust to rounding, also in float32)."""

_PD_RTOL = 1e-13
# A computed eigenvalue is only known to about eps·λ_max (2e-16·λ_max); moments at or below this
# fraction of the largest are numerically zero. Below EIGEN_FLOOR_REL so balanced tensors pass.

CODES = (
    "non_positive_mass",
    "non_finite",
    "not_symmetric",
    "not_positive_definite",
    "triangle_inequality",
    "pseudo_inertia_not_psd",
)
"""Every InertiaDefect code, in the order `inertia_defects` tests them."""


@dataclass(frozen=True)
class InertiaDefect:
    """One failed physical-consistency criterion of a (mass, COM, inertia) triple."""

    code: str
    """One of CODES."""
    message: str
    """What is wrong, with the offending values."""
    values: dict[str, float | list] = field(default_factory=dict, compare=False)
    """The numbers behind the message (eigenvalues, the violated inequality), for programs."""


def principal_moments(inertia: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and axes of a symmetric 3x3 inertia tensor.

    The pairs are ordered so that axis k is, as far as possible, the one closest to the k-th
    coordinate axis: for a nearly diagonal tensor the moments read in the order Ixx, Iyy, Izz,
    which keeps messages comparable with the file.

    Args:
      inertia: (3, 3) tensor; only its symmetric part is used.

    Returns:
      (moments (3,), axes (3, 3)) with inertia ≈ axes @ diag(moments) @ axes.T; axes columns are
      orthonormal.
    """
    tensor = np.asarray(inertia, dtype=float)
    moments, axes = np.linalg.eigh(0.5 * (tensor + tensor.T))
    weight = np.abs(axes)
    best = max(itertools.permutations(range(3)), key=lambda perm: sum(weight[row, col] for row, col in enumerate(perm)))
    order = list(best)
    return moments[order], axes[:, order]


def pseudo_inertia(mass: float, com: ArrayLike, inertia: ArrayLike) -> np.ndarray:
    """The 4x4 pseudo-inertia matrix J = [[Σ, h], [hᵀ, m]] about the frame origin.

    Σ = ½tr(I_o)·1 − I_o with I_o the inertia about the origin, h = m·c. Built with Pinocchio,
    `pin.Inertia(m, c, I).toPseudoInertia().toMatrix()`. Pinocchio 4.1 refuses a tensor with a
    negative eigenvalue ("The 3d inertia should be positive") or an asymmetric one, which are
    cases a checker must still evaluate; for those J is computed from the definition above
    (the test suite checks that both ways agree where Pinocchio accepts the tensor).

    Args:
      mass: kg.
      com: centre of mass (3,), metres, in the frame the tensor's axes are given in.
      inertia: (3, 3) inertia about the COM, kg·m².

    Returns:
      (4, 4) array.
    """
    import pinocchio as pin

    mass = float(mass)
    com_v = np.asarray(com, dtype=float).reshape(3)
    tensor = np.asarray(inertia, dtype=float).reshape(3, 3)
    try:
        return np.array(pin.Inertia(mass, com_v, tensor).toPseudoInertia().toMatrix())
    except RuntimeError:
        return _pseudo_inertia_from_definition(mass, com_v, tensor)


def _pseudo_inertia_from_definition(mass: float, com: np.ndarray, tensor: np.ndarray) -> np.ndarray:
    origin = tensor + mass * (com @ com * np.eye(3) - np.outer(com, com))  # parallel axes
    sigma = 0.5 * np.trace(origin) * np.eye(3) - origin
    h = mass * com
    result = np.empty((4, 4))
    result[:3, :3] = sigma
    result[:3, 3] = result[3, :3] = h
    result[3, 3] = mass
    return result


def _fmt(values) -> str:
    return ", ".join(f"{v:#.3g}" for v in values)


def _triangle_violation(moments: np.ndarray, rtol: float) -> tuple[int, float] | None:
    """(index of the too-large moment, excess) when the largest moment exceeds the sum of the
    other two by more than rtol·(sum of all three); None otherwise."""
    big = int(np.argmax(moments))
    others = np.delete(moments, big)
    excess = float(moments[big] - others.sum())
    scale = float(np.abs(moments).sum())
    if excess > rtol * scale:
        return big, excess
    return None


def _is_positive_definite(moments: np.ndarray) -> bool:
    largest = float(np.max(moments))
    return largest > 0.0 and float(np.min(moments)) > _PD_RTOL * largest


def inertia_defects(
    mass: float, com: ArrayLike, inertia: ArrayLike, *, rtol: float = DEFAULT_RTOL
) -> list[InertiaDefect]:
    """Checks that (mass, com, inertia) can be the mass properties of a real rigid body.

    The criteria and why they hold are in the module docstring. Non-finite input stops the
    checks (nothing else can be computed); a non-symmetric tensor is reported and its symmetric
    part checked further; the pseudo-inertia test needs a positive mass and is skipped without.

    Args:
      mass: kg.
      com: centre of mass (3,), metres.
      inertia: (3, 3) inertia about the COM, kg·m², in any orientation.
      rtol: relative tolerance of the symmetry test (‖I − Iᵀ‖ ≤ rtol·‖I‖), of the triangle
        inequality (I_max ≤ I_mid + I_min + rtol·Σ|I_k|) and of the pseudo-inertia test (the
        Schur complement Σ − h hᵀ/m of J, whose eigenvalues must be ≥ −rtol·‖Σ‖).
        Positive definiteness uses a fixed numerical-zero threshold, I_min > 1e-13·I_max.

    Returns:
      The defects found, in the order of CODES; empty when the body is physically consistent.

    Raises:
      ValueError: com or inertia has the wrong shape.
    """
    com_v = np.asarray(com, dtype=float)
    tensor = np.asarray(inertia, dtype=float)
    if com_v.shape != (3,) or tensor.shape != (3, 3):
        raise ValueError(f"com must have shape (3,) and inertia (3, 3); got {com_v.shape} and {tensor.shape}")
    mass = float(mass)
    defects: list[InertiaDefect] = []

    bad = {
        name: value
        for name, value in (("mass", [mass]), ("com", com_v.tolist()), ("inertia", tensor.ravel().tolist()))
        if not np.all(np.isfinite(value))
    }
    if bad:
        listing = "; ".join(f"{name} {value}" for name, value in bad.items())
        return [InertiaDefect("non_finite", f"non-finite values: {listing}", bad)]

    if mass <= 0.0:
        defects.append(InertiaDefect("non_positive_mass", f"mass {mass:g} kg is not positive", {"mass": mass}))

    asymmetry = float(np.linalg.norm(tensor - tensor.T))
    norm = float(np.linalg.norm(tensor))
    if asymmetry > rtol * norm:
        defects.append(
            InertiaDefect(
                "not_symmetric",
                f"inertia is not symmetric: |I - I^T| = {asymmetry:.3g}, |I| = {norm:.3g}",
                {"asymmetry": asymmetry, "norm": norm},
            )
        )
    tensor = 0.5 * (tensor + tensor.T)

    moments, _ = principal_moments(tensor)
    if not _is_positive_definite(moments):
        defects.append(
            InertiaDefect(
                "not_positive_definite",
                f"principal moments {_fmt(moments)}: not all positive",
                {"eigenvalues": moments.tolist()},
            )
        )

    violation = _triangle_violation(moments, rtol)
    if violation is not None:
        big, excess = violation
        a, b = np.delete(moments, big)
        defects.append(
            InertiaDefect(
                "triangle_inequality",
                f"principal moments {_fmt(moments)}: {_fmt([moments[big]])} > {_fmt([a])} + "
                f"{_fmt([b])} (excess {excess:.3g})",
                {
                    "eigenvalues": moments.tolist(),
                    "largest": float(moments[big]),
                    "sum_of_others": float(a + b),
                    "excess": excess,
                },
            )
        )

    if mass > 0.0:
        second, tolerance = _pseudo_inertia_schur(mass, com_v, tensor, rtol)
        if second[0] < -tolerance:
            defects.append(
                InertiaDefect(
                    "pseudo_inertia_not_psd",
                    f"pseudo-inertia not positive semidefinite: second moments about the COM "
                    f"{_fmt(second)} kg·m² (eigenvalues of Σ - h hᵀ/m) must be >= 0",
                    {"second_moments": second.tolist(), "tolerance": tolerance},
                )
            )
    return defects


def _pseudo_inertia_schur(mass: float, com: np.ndarray, tensor: np.ndarray, rtol: float) -> tuple[np.ndarray, float]:
    # J ⪰ 0 is tested through its Schur complement: with m > 0, J ⪰ 0 ⇔ Σ − h hᵀ/m ⪰ 0. The
    # eigenvalues of J itself mix kg and kg·m² and, with the COM far from the origin, J is so
    # ill-conditioned that a negative eigenvalue drowns in rounding; the Schur complement is a
    # 3x3 matrix in kg·m² whose rounding error is ~eps·‖Σ‖. The tolerance is relative to that
    # scale (‖Σ‖ includes m|c|², the parallel-axis term that the subtraction cancels).
    j = pseudo_inertia(mass, com, tensor)
    sigma, h = j[:3, :3], j[:3, 3]
    schur = sigma - np.outer(h, h) / j[3, 3]
    second = np.linalg.eigvalsh(0.5 * (schur + schur.T))
    scale = max(float(np.linalg.norm(sigma, 2)), 0.5 * float(np.abs(np.trace(tensor))))
    return second, rtol * scale


def balance_inertia(inertia: ArrayLike) -> np.ndarray:
    """The smallest change to an inertia tensor that makes it physically consistent.

    The rule keeps the principal axes and adjusts principal moments only, like MuJoCo's
    `<compiler balanceinertia="true">`, but changes less: MuJoCo sets all three moments to their
    average whenever A + B >= C fails; here

    1. the tensor is symmetrised, ½(I + Iᵀ);
    2. principal moments below a floor, max(1e-12·I_max, 1e-12 kg·m²), are raised to it (a zero
       or negative moment becomes a tiny positive one; the floor stays above MuJoCo's mjMINVAL);
    3. if the largest moment exceeds the sum of the other two, the smallest moment is raised to
       I_max − I_mid plus a margin of min(1e-6·I_max, I_mid): the inequality then holds strictly
       and the raised moment stays at most I_max. (At the exact bound MuJoCo 3.17 still fails
       "inertia must satisfy A + B >= C": its own eigen-decomposition rounds the sum below the
       largest moment.) Raising rather than lowering keeps the largest moment (usually the
       well-known one) and never removes inertia; the usual cause is a dropped digit in the
       small moment (the public SoftFoot-Q ankle Izz 1.0468e-6, CAD 4.0468e-6, becomes
       2.619e-6).

    A tensor that already passes the checks comes back symmetrised and otherwise unchanged.

    Args:
      inertia: (3, 3) inertia about the COM, kg·m², finite.

    Returns:
      (3, 3) symmetric tensor that passes `inertia_defects` (for any positive mass and COM).

    Raises:
      ValueError: wrong shape or non-finite entries.
    """
    tensor = np.asarray(inertia, dtype=float)
    if tensor.shape != (3, 3) or not np.all(np.isfinite(tensor)):
        raise ValueError(f"inertia must be a finite (3, 3) array; got {tensor!r}")
    tensor = 0.5 * (tensor + tensor.T)
    moments, axes = principal_moments(tensor)
    if _is_positive_definite(moments) and _triangle_violation(moments, DEFAULT_RTOL) is None:
        return tensor

    floor = max(EIGEN_FLOOR_REL * float(np.max(moments)), EIGEN_FLOOR_ABS)
    new = np.maximum(moments, floor)
    order = np.argsort(new)
    small, mid, big = order
    if new[big] > new[mid] + new[small]:
        # The margin is capped at I_mid so that the raised moment does not exceed I_max.
        new[small] = new[big] - new[mid] + min(TRIANGLE_MARGIN_REL * new[big], new[mid])
    balanced = axes @ np.diag(new) @ axes.T
    return 0.5 * (balanced + balanced.T)
