"""The names footforge enumerates, each declared once: foot variants, the feet a policy trains
and walks on, tasks and policy types. Every other module imports them from here
(tests/test_layout.py fails on a second spelling of these lists). No imports beyond typing: cheap
for every layer, from the build to the command lines."""

from __future__ import annotations

from typing import Literal, get_args

Variant = Literal["full", "aof", "aff", "ball"]
VARIANTS: tuple[Variant, ...] = get_args(Variant)
"""What `footforge build --variant` makes: the 34-joint closed chain (full, the reference), the
open-chain approximations AOF and AFF, and ANYmal C's ball foot."""

DERIVED: tuple[str, ...] = ("aof", "aff")
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
