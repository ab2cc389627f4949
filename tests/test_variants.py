"""The foot variant as one object (footforge.variants.FootVariant): each property against the model
that `footforge build` makes of the variant, so that a property the code asks cannot drift from
the foot it stands for."""

from __future__ import annotations

import mujoco
import pytest

from footforge.variants import DERIVED, FEET, FOOT_VARIANTS, HAPTIC, TASKS, VARIANTS, foot_variant

LEGS = ("LF", "RF", "LH", "RH")


def _foot_hinges(model: mujoco.MjModel, leg: str) -> int:
    return sum(
        model.joint(j).name.startswith(f"{leg}_foot/") and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
        for j in range(model.njnt)
    )


def _sole_plates(model: mujoco.MjModel, leg: str) -> int:
    return sum(model.body(b).name.startswith(f"{leg}_foot/sole") for b in range(model.nbody))


@pytest.mark.parametrize("variant", VARIANTS)
def test_each_property_is_what_the_variants_build_is(built, variant):
    kind = foot_variant(variant)
    out, report = built[variant]
    model = mujoco.MjModel.from_xml_path(str(out / "robot.xml"))
    assert kind.name == variant
    # Passive joints: the hinges under each foot of the robot, and the foot the build reports.
    assert [_foot_hinges(model, leg) for leg in LEGS] == [kind.passive_joints_per_foot] * 4
    assert len(report.get("foot", {}).get("passive_joints", [])) == kind.passive_joints_per_foot
    assert kind.adaptive == ("foot" in report)  # built from the SoftFoot-Q description
    # The closed chain alone closes loops through equality constraints (and its build checks them).
    assert kind.closed_chain == (model.neq > 0) == ("closure_residual_at_home_m" in report)
    # Derived feet are compared with the closed chain's mass properties by their build.
    assert kind.derived == ("mass_properties_vs_full" in report)
    # AOF's sole is two plates, AFF's one; the closed chain's sole is its links, the ball has none.
    plates = [_sole_plates(model, leg) for leg in LEGS]
    assert plates == [2 if kind.split_sole else 1 if kind.derived else 0] * 4


def test_the_lists_and_rules_derive_from_the_variants():
    """DERIVED, the haptic rule and the plots' colours read the variants' properties: the derived feet
    are AOF and AFF, a haptic policy needs adaptive feet (the ball has none), and no two variants share
    a colour."""
    from footforge.envs import registry

    assert tuple(FOOT_VARIANTS) == VARIANTS
    assert DERIVED == ("aof", "aff")
    assert [v for v in VARIANTS if foot_variant(v).closed_chain] == ["full"]
    combos = set(registry())
    for task, policies in TASKS.items():
        for feet in FEET:
            for policy in policies:
                expected = policy not in HAPTIC or feet != "ball"
                assert ((task, feet, policy) in combos) == expected, (task, feet, policy)
    assert len({foot_variant(v).colour for v in VARIANTS}) == len(VARIANTS)
    with pytest.raises(ValueError, match="unknown foot variant 'hoof'"):
        foot_variant("hoof")
