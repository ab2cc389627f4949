"""What a term is: the declaration of one reward term or observation group.

A leaf of footforge.envs: the term functions (envs.rewards, envs.observations) and the
configuration that declares each term with its function (envs.config) both import these, and
this module imports neither, so that no import circle joins them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import jax
    from mujoco import mjx


NOT_SAVED = {"saved": False}
"""Field metadata: declared in code, not written to a run's config.json (functions, widths)."""


@dataclass(frozen=True)
class RewardTerm:
    """One reward term: its function and its scale."""

    compute: Callable = field(default=None, metadata=NOT_SAVED)
    """(rewards.Quantities, RewardParameters) -> the unscaled term (envs.rewards, whose docstrings give
    each term's formula and unit)."""
    scale: float = 0.0
    """Multiplies the term (and the policy step dt): positive rewards, negative penalises."""


class RewardParameters(Protocol):
    """The parameters the reward functions read besides the step's quantities (RewardConfig's)."""

    tracking_sigma: float
    """Width of the tracking kernels, (m/s)^2 and (rad/s)^2."""
    base_height_target_m: float
    """Base height the base-height term measures from, m."""
    feet_air_time_target_s: float
    """Air time a step must last to pay, s."""


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
