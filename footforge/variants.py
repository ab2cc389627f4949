"""The names footforge enumerates, each declared once: foot variants, the feet a policy trains
and walks on, tasks and policy types. Every other module imports them from here
(tests/test_layout.py fails on a second spelling of these lists). No imports beyond the standard
library: cheap for every layer, from the build to the command lines.

A foot variant is one object, FootVariant (`foot_variant(name)`): code asks it what the variant is
(`.closed_chain`, `.derived`, `.adaptive`, `.split_sole`) instead of comparing its name."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

Variant = Literal["full", "aof", "aff", "ball"]
VARIANTS: tuple[Variant, ...] = get_args(Variant)
"""What `footforge build --variant` makes: the 34-joint closed chain (full, the reference), the
open-chain approximations AOF and AFF, and ANYmal C's ball foot."""


@dataclass(frozen=True)
class FootVariant:
    """What a foot variant is, declared once; every test of a variant reads these properties."""

    name: Variant
    summary: str
    """The variant in a few words (`footforge build --help`)."""
    closed_chain: bool
    """The SoftFoot-Q's closed kinematic chain (equality constraints close its loops): the reference
    the others are judged against; stepped by CPU MuJoCo's Newton solver at a short step, never by MJX."""
    derived: bool
    """An open-chain approximation derived from the closed chain (mass properties lumped, passive
    joints fitted by `footforge validate --calibrate`)."""
    passive_joints_per_foot: int
    """Joints that the ground moves, per foot, in the built model (0: a rigid foot). The closed
    chain's joints are more than its freedoms: its loops close through equality constraints."""
    split_sole: bool
    """The sole in two plates that roll on their own (AOF), rather than one (AFF, the closed chain's links)."""
    colour: str
    """The variant's colour in every plot (matplotlib's names)."""

    @property
    def adaptive(self) -> bool:
        """Whether the foot adapts to the ground through passive joints: what haptic (BH, PH)
        policies sense, and what the SoftFoot-Q's description is needed to build."""
        return self.passive_joints_per_foot > 0


FOOT_VARIANTS: dict[str, FootVariant] = {
    "full": FootVariant("full", "34-joint closed chain", True, False, 31, False, "black"),
    "aof": FootVariant("aof", "split sole, 4 passive DOF", False, True, 4, True, "tab:blue"),
    "aff": FootVariant("aff", "flat sole, 2 passive DOF", False, True, 2, False, "tab:orange"),
    "ball": FootVariant("ball", "ANYmal C's standard foot", False, False, 0, False, "tab:green"),
}
"""Every variant's properties, in VARIANTS' order (tests/test_variants.py checks them against the builds)."""


def foot_variant(name: str) -> FootVariant:
    """The variant called `name` (one of VARIANTS). Raises ValueError for another name: the command
    lines refuse one before it gets here."""
    try:
        return FOOT_VARIANTS[name]
    except KeyError:
        raise ValueError(f"unknown foot variant {name!r}: one of {', '.join(VARIANTS)}") from None


DERIVED: tuple[str, ...] = tuple(v for v in VARIANTS if FOOT_VARIANTS[v].derived)
"""The open-chain approximations, derived from the closed chain: their passive joints are what
`footforge validate --calibrate` fits."""

VALIDATED: tuple[str, ...] = DERIVED + ("ball",)
"""The variants `footforge validate` compares with the closed chain (`--variant all`)."""

Feet = Literal["ball", "aff", "aof"]
FEET: tuple[Feet, ...] = get_args(Feet)
"""The feet the MJX environments train on (the closed chain is too slow and stiff for MJX)."""

PLAY_FEET: tuple[Variant, ...] = FEET + ("full",)
"""The feet a trained policy can walk on in CPU MuJoCo: the training feet and the closed chain."""

PolicyType = Literal["B", "BH", "P", "PH"]
HAPTIC: tuple[str, ...] = ("BH", "PH")
"""Policy types that read the passive foot joints (they need adaptive feet)."""
PERCEPTIVE: tuple[str, ...] = ("P", "PH")
"""Policy types that read the height scan (rough terrain)."""

TASKS: dict[str, tuple[PolicyType, ...]] = {"flat": ("B", "BH"), "rough": ("B", "P", "BH", "PH")}
"""Each task's policy types: B blind, P perceptive (height scan), H haptic (passive foot joints)."""
