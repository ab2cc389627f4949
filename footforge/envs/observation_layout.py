"""The observation vector of a policy type: which groups it reads, in which order, how wide.

Derived from the configuration (ObservationConfig's fields in order, each group's readers and
width; envs.observations holds what each group reads).
"""

from __future__ import annotations

from dataclasses import fields

from footforge.envs.config import EnvConfig
from footforge.envs.terms import ObservationTerm


def terms(config: EnvConfig) -> list[tuple[str, ObservationTerm]]:
    """(name, term) of every group this policy type reads, in observation order."""
    o = config.observations
    reads = {"always": True, "haptic": config.haptic, "perceptive": config.perceptive, "pd_targets": o.pd_targets}
    out = []
    for f in fields(o):
        term = getattr(o, f.name)
        if isinstance(term, ObservationTerm) and reads[term.read_by]:
            out.append((f.name, term))
    return out


def width(config: EnvConfig, term: ObservationTerm, n_passive: int) -> int:
    """The number of values of `term`: its width, or one per passive foot joint or scan point."""
    return {"passive_joints": n_passive, "scan_points": config.height_scan.num_points}.get(term.width, term.width)  # type: ignore[arg-type]


def layout(config: EnvConfig, n_passive: int) -> list[tuple[str, int]]:
    """(name, width) of each slice of the observation, in order, for this policy type."""
    return [(name, width(config, term, n_passive)) for name, term in terms(config)]


def size(config: EnvConfig, n_passive: int) -> int:
    return sum(w for _, w in layout(config, n_passive))


def scale(config: EnvConfig, name: str) -> float | tuple[float, ...]:
    """The factor the environment multiplies group `name` by (a tuple for the command: vx, vy,
    yaw rate)."""
    return getattr(config.observations, name).scale


def description(config: EnvConfig, name: str) -> str:
    """What group `name` holds and in which unit (its reading function's docstring)."""
    return getattr(config.observations, name).read.__doc__.strip()


def passive_joints_of(config: EnvConfig, observation_size: int) -> int:
    """The number of passive foot joints a policy of `config` reads, from its observation width
    (haptic policies read each one's angle and velocity; the others none)."""
    if not config.haptic:
        return 0
    return (observation_size - size(config, 0)) // 2
