"""The physics settings of each contact model (EnvConfig.contact_model), as one table.

    row = resolve("stance", "aof", float64_physics=False, on_heightfield=True)

A row holds what a contact model sets on the build's MuJoCo model for some feet, precisions and
grounds: the physics step and the fewest solver iterations it needs (envs.physics,
envs.with_contact_model and anymal.check_contact_model read them), and the contact settings
anymal.load_robot writes over the build's (cone, impratio, solimp, solref, integrator). None in a
setting keeps the build's own, untouched (elliptic cone, impratio 10, implicitfast; on its colliders
solimp 0.99/0.999/0.001 and solref (0.004, 1)); None in a selector (feet, precision, ground) is any.

Resolution: the first row whose selectors match wins, so a narrower row stands before a wider
one (tests/test_contact_physics.py checks that every row is the first match somewhere, and that
every contact model, training feet, precision and ground finds one). resolve() reads
CONTACT_PHYSICS at each call: an experiment may put a row in front of it for a while
(benchmarks/divergence_history.py lifts a minimum that way).

The measurements behind each row: docs/defaults.md, "Physics per contact model, feet and
precision", whose table is as_markdown()'s (the test compares them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

from footforge.envs.config import ContactModel
from footforge.errors import InputError
from footforge.tables import markdown_table
from footforge.variants import DERIVED

Precision = Literal["float32", "float64"]
Ground = Literal["plane", "heightfield"]
Cone = Literal["pyramidal", "elliptic"]
Integrator = Literal["euler", "implicitfast"]

DEFAULT_ITERATIONS = (4, 8)
"""(Newton, line-search) iterations envs.physics sets where a row has no minimum ('fast'): MuJoCo
Playground trains at 1-4 Newton iterations."""


@dataclass(frozen=True)
class ContactPhysics:
    """One row: the physics of `contact_model` on the feet, precisions and grounds it selects."""

    contact_model: ContactModel
    feet: tuple[str, ...] | None
    """Feet the row applies to (footforge.variants); None: any, the closed chain's too."""
    precision: tuple[Precision, ...] | None
    """MJX's float precision (EnvConfig.float64_physics); None: either."""
    ground: tuple[Ground, ...] | None
    """"plane" (flat task) or "heightfield" (a terrain); None: either. Step and iterations must not
    depend on it: envs.physics and envs.with_contact_model set them before a ground is chosen."""
    sim_dt_s: float
    """Physics step envs.physics sets at the 50 Hz policy step, s."""
    max_sim_dt_s: float | None
    """Longest step the contact model holds a stance at, s (refused above, and
    envs.with_contact_model shortens a longer one); None: no limit."""
    min_iterations: tuple[int, int] | None
    """Fewest (Newton, line-search) solver iterations per step (refused below; envs.physics sets
    them); None: no minimum, envs.physics then sets DEFAULT_ITERATIONS."""
    cone: Cone | None
    """Friction cone (mjOption.cone); None: the build's (elliptic)."""
    impratio: float | None
    """Friction-to-normal impedance ratio (mjOption.impratio): the friction rows' regularisation is
    the normal's / impratio. None: the build's (10)."""
    solimp: tuple[float, float, float] | None
    """First three of every geom's solimp: impedance at zero and at full penetration (the share of
    the constraint force kept), and the width between them, m. None: the build's."""
    solref: tuple[float, float] | None
    """Every geom's solref: (time constant s, damping ratio), or MuJoCo's direct form (-stiffness
    1/s^2, -damping 1/s). Every geom alike, so MuJoCo's mixing of two geoms' solref changes nothing.
    None: the build's, (0.004, 1) on its colliders, whose 4 ms time constant MuJoCo raises to two steps
    where that is longer (5 ms at 2.5 ms)."""
    integrator: Integrator | None
    """mjOption.integrator; None: the build's (implicitfast)."""
    reason: str
    """Why, in a line or two; the measurements are in docs/defaults.md."""

    def matches(self, contact_model: str, feet: str, precision: str, ground: str) -> bool:
        return (
            self.contact_model == contact_model
            and (self.feet is None or feet in self.feet)
            and (self.precision is None or precision in self.precision)
            and (self.ground is None or ground in self.ground)
        )


_STIFF = (0.99, 0.999, 0.001)
"""'stance''s impedance (the build's): 99-99.9 % of the constraint force kept, so the friction's
regularisation, and with it the creep speed, is about 1/20 of MuJoCo's default (0.9-0.95)."""
_SOFTER = (0.97, 0.995, 0.001)
"""'stance''s impedance where float32 solves the stiff one too inexactly: the best compromise measured
between an inexact solve (stiffer) and creep by its regularisation (softer)."""
_SOFTER_NORMAL = (-10000.0, -400.0)
"""The adaptive feet's float32 solref, direct form: the build's damping at 2.5 ms (400 1/s, 2 / the
5 ms of two steps) with a quarter of its stiffness (1e4, not 4e4 1/s^2: damping ratio 2, not 1)."""


def _stance(
    feet: tuple[str, ...] | None,
    precision: tuple[Precision, ...] | None,
    ground: tuple[Ground, ...] | None,
    *,
    min_iterations: tuple[int, int],
    solimp: tuple[float, float, float],
    solref: tuple[float, float] | None,
    reason: str,
) -> ContactPhysics:
    """A 'stance' row. Every one steps at 2.5 ms at most: at 5 ms the friction's time constant is
    10 ms (MuJoCo clamps it to two steps) and a ball foot chatters and walks even at 16/50
    iterations. Pyramidal cone, impratio 10: the friction's regularisation, and with it the creep,
    a tenth of the normal's. Semi-implicit Euler (joint damping still implicit: eulerdamp stays on),
    as MuJoCo Playground's quadrupeds: implicitfast adds the actuators' velocity derivative (kv) to
    the mass matrix after the constraint solve, so the contact forces, solved for the plain mass
    matrix, no longer produce the accelerations they were solved for; with friction this stiff
    that mismatch threw ball robots metres up within 7 steps."""
    return ContactPhysics(
        "stance",
        feet,
        precision,
        ground,
        sim_dt_s=0.0025,
        max_sim_dt_s=0.0025,
        min_iterations=min_iterations,
        cone="pyramidal",
        impratio=10.0,
        solimp=solimp,
        solref=solref,
        integrator="euler",
        reason=reason,
    )


CONTACT_PHYSICS: tuple[ContactPhysics, ...] = (
    ContactPhysics(
        "fast",
        None,
        None,
        None,
        sim_dt_s=0.005,
        max_sim_dt_s=None,
        min_iterations=None,
        cone="pyramidal",
        impratio=1.0,
        solimp=(0.9, 0.95, 0.001),
        solref=None,
        integrator=None,
        reason="MuJoCo's defaults at the baselines' 5 ms x 4, as MuJoCo Playground trains: stable and cheap, "
        "but a robot at rest sinks and slides 150-180 mm in 10 s.",
    ),
    ContactPhysics(
        "build",
        None,
        None,
        None,
        sim_dt_s=0.0025,
        max_sim_dt_s=None,
        min_iterations=(16, 50),
        cone=None,
        impratio=None,
        solimp=None,
        solref=None,
        integrator=None,
        reason="The built scene's elliptic contact, converged: with fewer iterations its stiff friction "
        "diverges from any moving start.",
    ),
    _stance(
        ("ball",),
        ("float32",),
        ("heightfield",),
        min_iterations=(8, 16),
        solimp=_SOFTER,
        solref=None,
        reason="In float32 a heightfield contact's depth is too coarse for the stiff impedance: a resting "
        "foot flickers out of contact and the robot is thrown.",
    ),
    _stance(
        ("ball",),
        None,
        None,
        min_iterations=(8, 16),
        solimp=_STIFF,
        solref=None,
        reason="Stiff friction holds the stance; with fewer iterations the solve diverges under actions "
        "or lets a standing robot creep.",
    ),
    _stance(
        ("aff",),
        ("float32",),
        None,
        min_iterations=(16, 16),
        solimp=_SOFTER,
        solref=_SOFTER_NORMAL,
        reason="float32 solves light links' stiff rows inexactly; a softer normal stills the sole's jumping "
        "contact points. At 8/16 a spawn slid 45 mm.",
    ),
    _stance(
        ("aof",),
        ("float32",),
        None,
        min_iterations=(8, 16),
        solimp=_SOFTER,
        solref=_SOFTER_NORMAL,
        reason="As AFF; AOF stands, and survives an untrained policy's random actions, at 8/16.",
    ),
    _stance(
        DERIVED,
        ("float64",),
        None,
        min_iterations=(16, 16),
        solimp=_STIFF,
        solref=None,
        reason="float64 solves the stiff impedance on the adaptive feet; at 8/16 some robots diverged "
        "under random actions.",
    ),
)
"""The physics of every contact model, first match wins (module docstring)."""


def resolve(contact_model: str, feet: str, float64_physics: bool, on_heightfield: bool) -> ContactPhysics:
    """The row of CONTACT_PHYSICS that `contact_model` takes on `feet` in float64 or float32 physics,
    on a heightfield or a plane: the first that matches.

    Raises:
      InputError: an unknown contact model, or feet it has no row for ('stance' on the closed chain).
    """
    models = get_args(ContactModel)
    if contact_model not in models:
        raise InputError(f"unknown contact model '{contact_model}'", fix=f"use one of {', '.join(models)}")
    precision = "float64" if float64_physics else "float32"
    ground = "heightfield" if on_heightfield else "plane"
    for row in CONTACT_PHYSICS:
        if row.matches(contact_model, feet, precision, ground):
            return row
    raise InputError(
        f"contact_model '{contact_model}' has no physics for {feet} feet in {precision} on a {ground}",
        fix="use contact_model 'build' or 'fast' (envs.contact_physics.CONTACT_PHYSICS lists each model's rows)",
    )


def as_markdown(rows: tuple[ContactPhysics, ...] = CONTACT_PHYSICS) -> str:
    """`rows` as the Markdown table of docs/defaults.md ("Physics per contact model, feet and precision")."""

    def either(values) -> str:
        return "any" if values is None else ", ".join(values)

    def build_s(value) -> str:
        if value is None:
            return "build's"
        if isinstance(value, tuple):
            return " / ".join(f"{v:g}" for v in value)
        return f"{value:g}" if isinstance(value, float) else str(value)

    header = (
        "contact model",
        "feet",
        "precision",
        "ground",
        "step",
        "max step",
        "min iterations (Newton / line search)",
        "cone",
        "impratio",
        "solimp",
        "solref",
        "integrator",
        "why",
    )
    rows_out = []
    for r in rows:
        iterations = (
            "none ({} / {})".format(*DEFAULT_ITERATIONS)
            if r.min_iterations is None
            else "{} / {}".format(*r.min_iterations)
        )
        rows_out.append(
            [
                r.contact_model,
                either(r.feet),
                either(r.precision),
                either(r.ground),
                f"{r.sim_dt_s * 1e3:g} ms",
                "none" if r.max_sim_dt_s is None else f"{r.max_sim_dt_s * 1e3:g} ms",
                iterations,
                build_s(r.cone),
                build_s(r.impratio),
                build_s(r.solimp),
                build_s(r.solref),
                build_s(r.integrator),
                r.reason,
            ]
        )
    lines = markdown_table(header, rows_out)
    return "\n".join(lines) + "\n"
