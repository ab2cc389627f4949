"""What a term is: the declaration of one reward term or observation group.

A leaf of footforge.envs: the term functions (envs.rewards, envs.observations) and the
configuration that declares each term with its function (envs.config) both import these, and
this module imports neither, so that no import circle joins them.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from footforge.errors import InputError

if TYPE_CHECKING:
    import jax
    from mujoco import mjx


NOT_SAVED = {"saved": False}
"""Field metadata: declared in code, not written to a run's config.json (functions, widths)."""


@dataclass(frozen=True, init=False)
class RewardTerm:
    """One reward term: its function, its scale and its own parameters, declared on one line of
    RewardConfig, e.g. `RewardTerm(rewards.lin_vel_xy, 1.0, sigma=0.25)`.

    The function takes the step's quantities (rewards.Quantities) and, as keyword-only arguments,
    exactly the parameters named here (checked when the term is made). config.json holds a term as
    {"scale": ..., "params": {...}}; `--set env.rewards.<term>.params.<name>=...` sets one."""

    compute: Callable = field(default=None, metadata=NOT_SAVED)
    """(rewards.Quantities, **params) -> the unscaled term (envs.rewards, whose docstrings give each
    term's formula and unit)."""
    scale: float = 0.0
    """Multiplies the term (and the policy step dt): positive rewards, negative penalises."""
    params: dict[str, Any] = field(default_factory=dict)
    """The function's own parameters by name (a kernel's width, a target height, ...), in their units."""

    def __init__(
        self,
        compute: Callable | None = None,
        scale: float = 0.0,
        params: Mapping[str, Any] | None = None,
        **named: Any,
    ):
        # Parameters come by name (the declarations' form) or as one mapping (dataclasses.replace's
        # and rl.config.from_dict's form).
        object.__setattr__(self, "compute", compute)
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "params", {**(params or {}), **named})
        if compute is not None:
            takes = {
                p.name
                for p in inspect.signature(compute).parameters.values()
                if p.kind is inspect.Parameter.KEYWORD_ONLY
            }
            if set(self.params) != takes:
                name = getattr(compute, "__name__", repr(compute))
                raise InputError(
                    f"reward term {name}: parameters {sorted(self.params)} given, its function takes {sorted(takes)}",
                    fix=f"give exactly: {', '.join(sorted(takes)) or 'none'} (a run's config.json: "
                    f'"rewards": {{"{name}": {{"params": {{...}}}}}})',
                )

    def __hash__(self) -> int:  # params is a dict: hashed by its items, so that configurations stay hashable
        return hash((self.compute, self.scale, tuple(sorted(self.params.items()))))

    def __call__(self, q) -> jax.Array:
        """The unscaled term of a step's quantities (rewards.Quantities), with this term's parameters."""
        return self.compute(q, **self.params)


@dataclass(frozen=True)
class ObservationTerm:
    """One observation group: its reading function, width and readers (declared in code), and
    its scale and noise (configurable)."""

    read: ObservationReader = field(default=None, metadata=NOT_SAVED)
    """(env, data, info) -> the group's value in its unit (envs.observations, whose docstrings
    give what each holds)."""
    width: int | str = field(default=0, metadata=NOT_SAVED)
    """Number of values, or "passive_joints" / "scan_points": one per passive foot joint / scan point."""
    read_by: str = field(default="always", metadata=NOT_SAVED)
    """Which policies read it: "always", "haptic" (BH, PH), "perceptive" (P, PH), "pd_targets"
    (where ObservationConfig.pd_targets)."""
    scale: float | tuple[float, ...] = 1.0
    """Factor the noisy value is multiplied by (per component for a tuple)."""
    noise: float = 0.0
    """Half-width of the uniform noise added before scaling, in the group's unit (where
    ObservationConfig.noise)."""


class ObservedEnv(Protocol):
    """What an observation group's reading function reads of its environment
    (footforge.envs.locomotion.LocomotionEnv)."""

    robot: Any
    """footforge.envs.anymal.Robot: the index tables (actuated_qpos, actuated_dof, passive_qpos, ...)."""
    default_q: jax.Array
    """The actuated joints' default angles, rad."""

    def base_state(self, data: mjx.Data) -> tuple[jax.Array, jax.Array, jax.Array]:
        """(linear velocity m/s, angular velocity rad/s, unit gravity), base frame."""

    def height_scan(self, data: mjx.Data) -> jax.Array:
        """The clipped terrain heights under the scan points, m."""


ObservationReader = Callable[["ObservedEnv", "mjx.Data", dict], "jax.Array"]
"""An observation group's reading function: (environment, MJX data, the step's info) -> its value."""
