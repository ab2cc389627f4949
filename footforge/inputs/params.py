"""Variant parameters: the numbers `footforge build` needs beyond the description and sidecar.

Read from a YAML file (default: descriptions/softfoot_q/config/variant_params.yaml, documented
there field by field) into frozen dataclasses.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal, overload

from footforge.inputs.description import descriptions_dir
from footforge.inputs.yaml_reader import YamlReader, read_yaml
from footforge.variants import foot_variant

PARAMS_FORMAT = 1
"""The parameter file's `format:` this footforge reads."""


def default_params_path() -> Path:
    return descriptions_dir() / "softfoot_q" / "config" / "variant_params.yaml"


@dataclass(frozen=True)
class PassiveJoint:
    stiffness: float
    """N m/rad."""
    damping: float
    """N m s/rad."""
    armature: float
    """kg m^2."""
    springref: float
    """Spring rest angle, rad."""


SOLE_CONTACT_SHAPES = ("box", "spheres", "capsules")
"""How a derived foot's sole plates collide (FootContact.sole)."""


@dataclass(frozen=True)
class FootContact:
    """The collision geometry of a derived foot (AFF, AOF): what touches the ground."""

    sole: str = "box"
    """'box': each sole plate collides through the box enclosing the links it replaces (exact
    envelope, but MJX's box-plane and box-heightfield tests are its costliest and give 4 contacts
    each); 'spheres': through a grid of spheres, as MuJoCo Playground's quadrupeds touch the
    ground (one contact per sphere on a plane); 'capsules': through rows of capsules along the
    foot's length (two contacts each on a plane), which, unlike spheres, leave no gap along the
    sole for an edge or a bar to poke through. Their lowest points lie on the box's bottom face
    and inside its footprint, so on flat ground the plate stands where the box would."""
    grid: tuple[int, int] = (2, 2)
    """Spheres per sole plate along the foot's length (x) and width (y); for capsules, segments
    along x and rows along y. With more than one along an axis the outer ones reach the box's
    edges; with one they sit on its centre line."""
    radius_m: float = 0.01
    """Sphere or capsule radius, m."""
    upper_collisions: bool = True
    """Whether the parts above the sole (ankle, arch and roll links) collide too. Off, only the sole
    touches the ground: each of those boxes costs MJX a collision test and four contacts per
    step."""


@dataclass(frozen=True)
class FullChainSettings:
    timestep: float
    """s."""
    iterations: int
    tolerance: float
    closure_solref: tuple[float, float]
    closure_solimp: tuple[float, float, float]
    contact_solref: tuple[float, float]
    """Contact solref of the closed chain's (and its robot's) collision geoms."""


@dataclass(frozen=True)
class VariantParams:
    source: Path
    full: FullChainSettings
    simplified_timestep: float
    """s; AFF, AOF and ball."""
    aff: dict[str, PassiveJoint]
    """ankle_pitch, ankle_roll."""
    aof: dict[str, PassiveJoint]
    """ankle_pitch, ankle_roll, sole_front, sole_back."""
    aof_split_x: float
    """m; chain links ahead of this plane form the front sole."""
    aof_sole_range: tuple[float, float]
    """rad."""
    sole_lift_m: dict[str, float]
    """Per derived variant (aff, aof): how far the sole's collision box is raised above the closed
    chain's lowest point at the slack reference pose, m. Under load the chain flattens and the
    ankle sinks; a lift lets the rigid sole stand at the loaded chain's height (calibrated)."""
    foot_contact: dict[str, FootContact]
    """Per derived variant (aff, aof): its collision geometry (the file's `aff.collision`,
    `aof.collision`; the top-level `contact` block is the contact model)."""
    rig_payload_mass: float
    """kg."""
    rig_slider_damping: float
    """N s/m."""
    contact_solref: tuple[float, float]
    """MuJoCo solref (timeconst s, damping ratio) of the robot's and feet's collision geoms in the
    AFF, AOF and ball models: the sole pad's contact stiffness, dominant over the ground's (see
    footforge.mjcf.elements.CONTACT_SOLMIX). The closed chain has its own (full.contact_solref)."""
    contact_solimp: tuple[float, float, float]
    """MuJoCo solimp (dmin, dmax, width m) of the robot models' collision geoms (the drop-test
    rigs keep MuJoCo's default, under which the feet were calibrated)."""
    contact_cone: str
    """Friction cone of the robot models: 'elliptic' or 'pyramidal' (rigs: pyramidal)."""
    contact_impratio: float
    """Ratio of frictional to normal constraint impedance (MuJoCo option impratio) of the robot models."""

    def joints_for(self, variant: str) -> dict[str, PassiveJoint]:
        """The passive joints of a derived variant (aff or aof)."""
        return self.aff if variant == "aff" else self.aof

    def contact_solref_for(self, variant: str) -> tuple[float, float]:
        return self.full.contact_solref if foot_variant(variant).closed_chain else self.contact_solref


_JOINTS = {"aff": ("ankle_pitch", "ankle_roll"), "aof": ("ankle_pitch", "ankle_roll", "sole_front", "sole_back")}


def _passive(r: YamlReader) -> PassiveJoint:
    r.check_keys({"stiffness", "damping", "armature", "springref"})
    return PassiveJoint(
        stiffness=r.get("stiffness").float(min_value=0.0),
        damping=r.get("damping").float(min_value=0.0),
        armature=r.get("armature", 0.0).float(min_value=0.0),
        springref=r.get("springref", 0.0).float(),
    )


@overload
def _pair(r: YamlReader, n: Literal[2]) -> tuple[float, float]: ...
@overload
def _pair(r: YamlReader, n: Literal[3]) -> tuple[float, float, float]: ...
def _pair(r: YamlReader, n: int) -> tuple[float, ...]:
    if not isinstance(r.data, list) or len(r.data) != n:
        raise r.fail(f"expected a list of {n} numbers, got {r.data!r}", f"give {n} numbers")
    return tuple(YamlReader(v, f"{r.path}[{i}]", r.file).float() for i, v in enumerate(r.data))


def _foot_contact(r: YamlReader) -> FootContact:
    default = FootContact()
    sole = r.check_keys({"sole", "grid", "radius_m", "upper_collisions"}).get("sole", default.sole).data
    if sole not in SOLE_CONTACT_SHAPES:
        raise r.get("sole").fail(f"unknown sole contact '{sole}'", f"use one of {', '.join(SOLE_CONTACT_SHAPES)}")
    grid_r = r.get("grid", list(default.grid))
    grid = _pair(grid_r, 2)
    if any(n != int(n) or not 1 <= n <= 8 for n in grid):
        raise grid_r.fail(f"bad grid {list(grid)}", "give two whole numbers from 1 to 8 (along x, along y)")
    if sole == "box":
        for key in ("grid", "radius_m"):
            if key in r.mapping():
                raise r.get(key).fail(
                    "a box sole has no grid or radius", "remove it, or choose sole: spheres or capsules"
                )
    upper = r.get("upper_collisions", default.upper_collisions).data
    if not isinstance(upper, bool):
        raise r.get("upper_collisions").fail(f"expected true or false, got {upper!r}", "write true or false")
    return FootContact(
        sole=sole,
        grid=(int(grid[0]), int(grid[1])),
        radius_m=r.get("radius_m", default.radius_m).float(min_value=1e-4, max_value=0.05),
        upper_collisions=upper,
    )


def _check_timeconst(r: YamlReader, solref: tuple[float, ...], timestep: float) -> None:
    if solref[0] < 2 * timestep:
        raise r.fail(
            f"timeconst {solref[0]} is below twice the timestep {timestep}",
            "MuJoCo cannot integrate a constraint faster than 2 steps: raise it or lower the timestep",
        )


def load_params(path: str | Path | None = None) -> VariantParams:
    """Reads a variant parameter file.

    Raises:
      InputError: missing file, bad YAML, a missing or unknown key, a bad value.
    """
    path = Path(path) if path else default_params_path()
    top = YamlReader(read_yaml(path, what="parameter file", fix="pass an existing file to --params"), "", path)
    top.check_keys({"format", "full", "simplified", "aff", "aof", "rig", "contact"})
    fmt = top.get("format")
    if fmt.data != PARAMS_FORMAT:
        raise fmt.fail(
            f"format {fmt.data!r} is not {PARAMS_FORMAT}, the one this footforge reads",
            f"write the file in format {PARAMS_FORMAT} (see the shipped {default_params_path().name})",
        )
    full = top.get("full")
    full.check_keys({"timestep", "iterations", "tolerance", "closure_solref", "closure_solimp", "contact_solref"})
    iterations = full.get("iterations").float(min_value=1)
    settings = FullChainSettings(
        timestep=full.get("timestep").float(min_value=1e-6),
        iterations=int(iterations),
        tolerance=full.get("tolerance").float(min_value=0.0),
        closure_solref=_pair(full.get("closure_solref"), 2),
        closure_solimp=_pair(full.get("closure_solimp"), 3),
        contact_solref=_pair(full.get("contact_solref"), 2),
    )
    for key in ("closure_solref", "contact_solref"):
        _check_timeconst(full.get(key), getattr(settings, key), settings.timestep)
    simplified = top.get("simplified")
    simplified.check_keys({"timestep"})
    variants, lifts, contacts = {}, {}, {}
    for variant, names in _JOINTS.items():
        r = top.get(variant)
        extra = {"sole_lift_m", "collision"} | ({"split_x", "sole_range"} if variant == "aof" else set())
        r.check_keys(set(names) | extra)
        variants[variant] = {n: _passive(r.get(n)) for n in names}
        lifts[variant] = r.get("sole_lift_m", 0.0).float(min_value=0.0, max_value=0.05)
        contacts[variant] = _foot_contact(r.get("collision", {}))
    aof = top.get("aof")
    sole_range = _pair(aof.get("sole_range"), 2)
    if sole_range[0] >= sole_range[1]:
        raise aof.get("sole_range").fail(f"empty range {list(sole_range)}", "give [lower, upper] with lower < upper")
    rig = top.get("rig")
    rig.check_keys({"payload_mass", "slider_damping"})
    contact = top.get("contact")
    contact.check_keys({"solref", "solimp", "cone", "impratio"})
    contact_solref = _pair(contact.get("solref"), 2)
    solimp = _pair(contact.get("solimp", [0.9, 0.95, 0.001]), 3)  # MuJoCo's default
    if not (0 < solimp[0] <= solimp[1] < 1 and solimp[2] > 0):
        raise contact.get("solimp").fail(
            f"bad solimp {list(solimp)}", "give [dmin, dmax, width] with 0 < dmin <= dmax < 1 and width > 0"
        )
    cone = contact.get("cone", "pyramidal").str()
    if cone not in ("elliptic", "pyramidal"):
        raise contact.get("cone").fail(f"unknown friction cone '{cone}'", "use elliptic or pyramidal")
    _check_timeconst(contact.get("solref"), contact_solref, simplified.get("timestep").float(min_value=1e-6))
    return VariantParams(
        source=path.resolve(),
        full=settings,
        simplified_timestep=simplified.get("timestep").float(min_value=1e-6),
        aff=variants["aff"],
        aof=variants["aof"],
        aof_split_x=aof.get("split_x").float(),
        aof_sole_range=sole_range,
        sole_lift_m=lifts,
        foot_contact=contacts,
        rig_payload_mass=rig.get("payload_mass").float(min_value=0.0),
        rig_slider_damping=rig.get("slider_damping", 0.0).float(min_value=0.0),
        contact_solref=contact_solref,
        contact_solimp=solimp,
        contact_cone=cone,
        contact_impratio=contact.get("impratio", 1.0).float(min_value=1e-3),
    )
