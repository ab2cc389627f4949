"""Tests of footforge.inputs.inertia: the physical-consistency criteria and balance_inertia."""

import numpy as np
import pytest

from footforge.inputs.inertia import (
    CODES,
    balance_inertia,
    inertia_defects,
    principal_moments,
    pseudo_inertia,
)


def codes(defects):
    return [d.code for d in defects]


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def box_inertia(mass, x, y, z):
    return mass / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])


# The public SoftFoot-Q ankle: Izz 1.0468e-6 is a typo for 4.0468e-6.
ANKLE_MASS = 0.0181
ANKLE_COM = (0.0, 0.0, 0.0154)
ANKLE_TYPO = 1e-6 * np.array([[4.4972, -0.0012, -0.0027], [-0.0012, 1.8785, 0.0005], [-0.0027, 0.0005, 1.0468]])


def from_moments(moments, rotation=np.eye(3)):  # noqa: B008  (read, never changed)
    return rotation @ np.diag(moments) @ rotation.T


# ANYmal C depth cameras and hatch (principal moments of the published file).
CAMERA = from_moments([8.67e-06, 6.69e-04, 1.37e-03])
HATCH = from_moments([1e-20, -1e-19, 3e-03])


# -- good inertias -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "mass, com, inertia",
    [
        (2.0, (0.1, -0.2, 0.05), box_inertia(2.0, 0.3, 0.2, 0.1)),
        # A rod of radius 2 mm and length 0.5 m: moments 1e-6 and 0.0208, ratio 5e-5.
        (1.0, (0.0, 0.0, 0.25), np.diag([1.0 / 12 * 0.25 + 1e-6, 1.0 / 12 * 0.25 + 1e-6, 2e-6])),
        # A point-like sphere: 1 g, radius 1 mm.
        (1e-3, (0.0, 0.0, 0.0), 0.4 * 1e-3 * 1e-6 * np.eye(3)),
        # The ankle with the CAD value of Izz.
        (ANKLE_MASS, ANKLE_COM, ANKLE_TYPO + np.diag([0, 0, 3e-6])),
    ],
)
def test_physical_inertias_pass(mass, com, inertia):
    assert inertia_defects(mass, com, inertia) == []


def test_rotated_box_passes():
    rng = np.random.default_rng(0)
    rotation = random_rotation(rng)
    inertia = rotation @ box_inertia(0.5, 0.04, 0.04, 0.03) @ rotation.T
    assert inertia_defects(0.5, (0.01, 0.02, 0.03), inertia) == []


# -- each defect ---------------------------------------------------------------------------------


def test_non_positive_mass():
    defects = inertia_defects(0.0, (0, 0, 0), box_inertia(1.0, 0.1, 0.1, 0.1))
    assert codes(defects) == ["non_positive_mass"]
    assert codes(inertia_defects(-1.0, (0, 0, 0), box_inertia(1.0, 0.1, 0.1, 0.1))) == ["non_positive_mass"]


def test_non_finite_stops_the_checks():
    inertia = box_inertia(1.0, 0.1, 0.1, 0.1)
    inertia[0, 0] = np.nan
    defects = inertia_defects(1.0, (0, 0, 0), inertia)
    assert codes(defects) == ["non_finite"]
    assert "inertia" in defects[0].values
    assert codes(inertia_defects(np.inf, (0, 0, 0), box_inertia(1.0, 0.1, 0.1, 0.1))) == ["non_finite"]


def test_not_symmetric():
    inertia = box_inertia(1.0, 0.1, 0.2, 0.3)
    inertia[0, 1] = 1e-4
    assert codes(inertia_defects(1.0, (0, 0, 0), inertia)) == ["not_symmetric"]
    inertia[0, 1] = inertia[1, 0] * (1 + 1e-12) + 1e-20  # rounding noise is symmetric
    assert inertia_defects(1.0, (0, 0, 0), inertia) == []


def test_ankle_typo_breaks_the_triangle_inequality():
    defects = inertia_defects(ANKLE_MASS, ANKLE_COM, ANKLE_TYPO)
    assert codes(defects) == ["triangle_inequality", "pseudo_inertia_not_psd"]
    triangle = defects[0]
    assert "4.50e-06 > 1.88e-06 + 1.05e-06" in triangle.message
    assert triangle.values["excess"] == pytest.approx(4.4972e-6 - 1.8785e-6 - 1.0468e-6, rel=1e-3)
    # The pseudo-inertia's second moment about the COM along x is (Iyy + Izz - Ixx) / 2 < 0.
    assert min(defects[1].values["second_moments"]) == pytest.approx((1.8785e-6 + 1.0468e-6 - 4.4972e-6) / 2, rel=1e-3)


def test_anymal_depth_camera_breaks_the_triangle_inequality():
    rotation = random_rotation(np.random.default_rng(1))
    defects = inertia_defects(0.1, (0.01, 0, 0), from_moments([8.67e-06, 6.69e-04, 1.37e-03], rotation))
    assert "triangle_inequality" in codes(defects)
    assert "not_positive_definite" not in codes(defects)


def test_anymal_hatch_is_not_positive_definite():
    defects = inertia_defects(0.1, (0, 0, 0.05), HATCH)
    assert codes(defects)[0] == "not_positive_definite"
    assert "eigenvalues" in defects[0].values
    # Moments (0, 0, 3e-3) also break the triangle inequality: 3e-3 > 0 + 0.
    assert set(codes(defects)) == {"not_positive_definite", "triangle_inequality", "pseudo_inertia_not_psd"}


def test_thin_rod_limit_is_realizable_but_not_positive_definite():
    # Moments (0, a, a): a line mass. Physically realizable (pseudo-inertia PSD, triangle holds
    # with equality) but a simulator needs positive moments.
    assert codes(inertia_defects(1.0, (0, 0, 0.1), np.diag([0.0, 1e-3, 1e-3]))) == ["not_positive_definite"]


def test_pseudo_inertia_matches_the_formula():
    """Pinocchio's pseudo-inertia against its definition, also for a tensor Pinocchio refuses."""
    rng = np.random.default_rng(2)
    mass, com = 1.7, rng.normal(size=3) * 0.1
    rotation = random_rotation(rng)
    for moments in ([0.02, 0.03, 0.04], [0.01, 0.01, 0.05], [-0.01, 0.03, 0.04]):
        inertia = from_moments(moments, rotation)
        inertia_origin = inertia + mass * (com @ com * np.eye(3) - np.outer(com, com))
        sigma = 0.5 * np.trace(inertia_origin) * np.eye(3) - inertia_origin
        h = mass * com
        expected = np.zeros((4, 4))
        expected[:3, :3], expected[:3, 3], expected[3, :3], expected[3, 3] = sigma, h, h, mass
        np.testing.assert_allclose(pseudo_inertia(mass, com, inertia), expected, atol=1e-15)


def test_principal_moments_follow_the_coordinate_axes():
    moments, axes = principal_moments(ANKLE_TYPO)
    np.testing.assert_allclose(moments, [4.4972e-6, 1.8785e-6, 1.0468e-6], rtol=1e-3)
    np.testing.assert_allclose(axes @ np.diag(moments) @ axes.T, ANKLE_TYPO, atol=1e-18)


# -- balance_inertia -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name, mass, com, inertia",
    [
        ("ankle", ANKLE_MASS, ANKLE_COM, ANKLE_TYPO),
        ("camera", 0.1, (0.01, 0.0, 0.0), CAMERA),
        ("hatch", 0.1, (0.0, 0.0, 0.05), HATCH),
        ("asymmetric", 1.0, (0, 0, 0), box_inertia(1.0, 0.1, 0.2, 0.3) + np.triu(np.full((3, 3), 1e-4), 1)),
        ("negative", 1.0, (0, 0, 0), np.diag([-1e-3, 2e-3, 2.5e-3])),
    ],
)
def test_balance_inertia_repairs(name, mass, com, inertia):
    assert inertia_defects(mass, com, inertia), name
    balanced = balance_inertia(inertia)
    assert inertia_defects(mass, com, balanced) == []
    np.testing.assert_array_equal(balanced, balanced.T)
    # Idempotent: a balanced tensor comes back unchanged.
    np.testing.assert_array_equal(balance_inertia(balanced), balanced)


def test_balance_inertia_raises_the_smallest_moment_and_keeps_the_axes():
    rotation = random_rotation(np.random.default_rng(3))
    balanced = balance_inertia(from_moments([4.4972e-6, 1.8785e-6, 1.0468e-6], rotation))
    back = rotation.T @ balanced @ rotation  # in the original principal axes
    margin = 1e-6 * 4.4972e-6
    np.testing.assert_allclose(back, np.diag([4.4972e-6, 1.8785e-6, 2.6187e-6 + margin]), atol=1e-17)


def test_balance_inertia_keeps_the_raised_moment_below_the_largest():
    # Hatch-like: two zero moments. Floored to 1e-12, then one raised: a rod (3e-3, 3e-3, 1e-12).
    moments, _ = principal_moments(balance_inertia(HATCH))
    np.testing.assert_allclose(np.sort(moments), [1e-12, 3e-3, 3e-3], rtol=1e-9)
    assert moments.max() == pytest.approx(3e-3, rel=1e-12)  # the largest is kept


def test_balance_inertia_leaves_valid_tensors_alone():
    inertia = box_inertia(2.0, 0.3, 0.2, 0.1) + 1e-5 * np.array([[0, 1, 0], [1, 0, 0], [0, 0, 0]])
    np.testing.assert_array_equal(balance_inertia(inertia), inertia)


def test_balance_inertia_floor_is_above_mujoco_minval():
    balanced = balance_inertia(np.diag([0.0, 0.0, 0.0]))
    assert np.all(np.linalg.eigvalsh(balanced) >= 1e-12)


def test_balance_inertia_rejects_non_finite():
    with pytest.raises(ValueError):
        balance_inertia(np.full((3, 3), np.nan))


# -- the full condition against the eigen-criteria ------------------------------------------------


def random_body(rng: np.random.Generator, physical: bool):
    """A random body: moments drawn at a random size and orientation, then the largest pushed
    clearly under (physical) or over the sum of the other two, sometimes with a negative moment;
    COM offsets from a tenth to ten body sizes, masses over five orders of magnitude."""
    mass = 10.0 ** rng.uniform(-3, 2)
    size = 10.0 ** rng.uniform(-3, -0.5)
    moments = rng.uniform(0.1, 1.0, size=3) * mass * size**2
    order = np.argsort(moments)
    bound = moments[order[0]] + moments[order[1]]
    if physical:
        moments[order[2]] = max(moments[order[1]], bound * rng.uniform(0.05, 0.95))
    else:
        moments[order[2]] = bound * rng.uniform(1.05, 3.0)
        if rng.integers(4) == 0:
            moments[order[0]] = -moments[order[0]]
    com = rng.normal(size=3) * size * 10.0 ** rng.uniform(-1, 1)
    return mass, com, from_moments(moments, random_rotation(rng)), moments


def test_pseudo_inertia_criterion_agrees_with_the_eigen_criteria():
    """J ⪰ 0 exactly when the principal moments are >= 0 and obey the triangle inequality."""
    rng = np.random.default_rng(20240601)
    for index in range(400):
        physical = index % 2 == 0
        mass, com, inertia, _ = random_body(rng, physical)
        defects = set(codes(inertia_defects(mass, com, inertia)))
        eigen_ok = not defects & {"not_positive_definite", "triangle_inequality"}
        assert ("pseudo_inertia_not_psd" not in defects) == eigen_ok == physical, (mass, com, inertia)


def test_physical_bodies_are_sums_of_point_masses():
    """Realizability, constructively: six point masses m/6 at c ± a_k·e_k along the principal
    axes e_k, with a_k² = 3σ_k/m and σ_k = (I_j + I_k' − I_k)/2 the second moments about the
    COM, have the pseudo-inertia Pinocchio computes for (m, c, I); a sum of PSD rank-one
    matrices ∑ m_i [p_i; 1][p_i; 1]ᵀ."""
    rng = np.random.default_rng(7)
    for _ in range(50):
        mass, com, inertia, _ = random_body(rng, physical=True)
        moments, axes = principal_moments(inertia)
        second = 0.5 * moments.sum() - moments
        points = [com + sign * np.sqrt(3 * s / mass) * axes[:, k] for k, s in enumerate(second) for sign in (1, -1)]
        j_points = sum(mass / 6 * np.outer(np.append(p, 1), np.append(p, 1)) for p in points)
        j = pseudo_inertia(mass, com, inertia)
        np.testing.assert_allclose(j_points, j, rtol=1e-9, atol=1e-12 * np.abs(j).max())


def test_every_code_is_reachable_and_defects_come_in_the_order_of_codes():
    """CODES lists what inertia_defects can say, in the order it says it: each code is produced by
    a body built to break its criterion, and random bodies (physical or not) produce no other code
    and list theirs in CODES order."""
    asymmetric = box_inertia(1.0, 0.1, 0.2, 0.3)
    asymmetric[0, 1] = 1e-4
    made = {
        "non_positive_mass": (-1.0, (0, 0, 0), box_inertia(1.0, 0.1, 0.1, 0.1)),
        "non_finite": (1.0, (np.nan, 0, 0), box_inertia(1.0, 0.1, 0.1, 0.1)),
        "not_symmetric": (1.0, (0, 0, 0), asymmetric),
        "not_positive_definite": (1.0, (0, 0, 0), HATCH),
        "triangle_inequality": (1.0, (0, 0, 0), np.diag([1.0, 1.0, 3.0])),  # 3 > 1 + 1
        # Moments 1, 1, 3 about the COM: second moments (1 + 1 - 3) / 2 < 0 along z.
        "pseudo_inertia_not_psd": (1.0, (0, 0, 0), np.diag([1.0, 1.0, 3.0])),
    }
    assert set(made) == set(CODES)
    for code, body in made.items():
        assert code in codes(inertia_defects(*body)), code
    rng = np.random.default_rng(3)
    seen = set()
    for physical in (True, False) * 100:
        found = codes(inertia_defects(*random_body(rng, physical=physical)[:3]))
        assert [CODES.index(c) for c in found] == sorted(CODES.index(c) for c in found), found
        seen.update(found)
    assert seen <= set(CODES) and seen
