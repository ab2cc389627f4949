"""ANYmal C as built by `footforge build`, prepared for MJX: indices, geom groups, solver settings.

The model is the build's scene.xml (robot.xml plus a floor), never a second hand-written model.
For MJX the only changes are the step, the solver iterations, and switching off collisions that
no task needs to be physical: hips; shank tubes on flat ground; the base and the thighs, whose
ground contact only ends episodes and is measured geometrically instead
(footforge.envs.locomotion.LocomotionEnv.contact_flags). Their colliders would otherwise be the
most of MJX's contact slots (83 of ball feet's 87 on flat ground), each of them constraint rows of
every Newton iteration (benchmarks/step_profile.py). The feet keep theirs; on a heightfield the
shank tubes collide as capsules (MJX has no cylinder-heightfield collision) and the adaptive
feet's sole boxes as grids of spheres, from their own rest pose (EnvConfig.heightfield_soles: the
two engines collide boxes with a heightfield differently, spheres alike). CPU MuJoCo
(load_robot(for_mjx=False)) keeps every other collider of the build.
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from footforge import constants as C
from footforge.envs.config import EnvConfig
from footforge.envs.contact_physics import resolve
from footforge.errors import InputError
from footforge.variants import foot_variant

FLOOR_GEOM = "floor"
GEOM_NONE, GEOM_BASE = 0, 1
"""Geom categories for contact checks; thigh geoms of leg i are 3 + i, its foot geoms 10 + i."""
GEOM_THIGH, GEOM_FOOT = 3, 10
GEOM_SHANK = 20
"""Shank tube of leg i on a heightfield (MJX): 20 + i. It collides, but is neither a foot nor a knee."""


@dataclass(frozen=True)
class Robot:
    model: mujoco.MjModel
    home_qpos: np.ndarray
    stand_qpos: np.ndarray
    """The build's `stand` keyframe: at rest on flat ground under the default PD targets (builds
    older than the keyframe: `home`)."""
    actuated_qpos: np.ndarray
    """qpos addresses of the 12 actuated joints, in constants.ACTUATED_JOINTS order."""
    actuated_dof: np.ndarray
    actuator_ids: np.ndarray
    """Actuator of each actuated joint, same order."""
    default_q: np.ndarray
    """Default joint angles (rad), same order."""
    q_limits: np.ndarray
    """(12, 2) joint ranges, rad."""
    haa: np.ndarray
    """Indices of the HAA joints within the 12."""
    passive_qpos: np.ndarray
    """qpos addresses of the passive foot joints (leg by leg), empty for ball feet."""
    passive_dof: np.ndarray
    passive_names: tuple[str, ...]
    """The passive joints, in the order of the haptic observations."""
    geom_category: np.ndarray
    """Per geom: GEOM_NONE, GEOM_BASE, GEOM_THIGH + leg index or GEOM_FOOT + leg index."""
    foot_sites: np.ndarray
    """Touchdown site of each leg's foot (LF, RF, LH, RH)."""
    floor_geom: int
    engine_model: mujoco.MjModel | None = None
    """Under EnvConfig.physics 'mujoco', and for the CPU runner (load_robot(for_mjx=False)): `model`
    with the sensors the C engine reads (footforge.envs.engine_mujoco.add_sensors), which MJX cannot
    load; the same physics."""


DEFAULT_BUILD_ROOT = Path("build")
"""Where the environments look for a feet's build without EnvConfig.build_dir: build/<feet>/,
relative to the working directory (the first README command writes build/aof/)."""


def build_dir(config: EnvConfig) -> Path:
    return Path(config.build_dir) if config.build_dir else DEFAULT_BUILD_ROOT / config.feet


def ensure_built(config: EnvConfig) -> Path:
    """The build folder of config.feet, checked. Environments never build: the training pipelines
    do (footforge.cli.train), and a library user runs `footforge build` first.

    Raises:
      InputError: the folder holds no scene.xml, or a build this footforge cannot use (another
        variant, an older build format, inputs changed since); never rebuilt silently, since the
        folder may hold a user's build from their own parameter file.
    """
    folder = build_dir(config)
    if not (folder / "scene.xml").is_file():
        raise InputError(
            f"{folder} holds no scene.xml",
            file=str(folder),
            fix=f"run footforge build --variant {config.feet} --out {folder}",
        )
    problem = build_problem(folder, config.feet)
    if problem:
        raise InputError(
            f"{folder} cannot be used: {problem}",
            file=str(folder / "build_report.json"),
            fix=f"rebuild it: footforge build --variant {config.feet} --out {folder} "
            "(add the --params or description flags it was built with)",
        )
    return folder


def build_problem(folder: Path, feet: str) -> str | None:
    """Why the build in `folder` does not fit feet `feet` and this footforge, or None.

    Read from its build_report.json: the variant, the build format (constants.BUILD_FORMAT), and
    the SHA-256 of each input file that still exists at its recorded path (a build carried to
    another machine keeps its recorded paths, which then do not exist there: not checked).
    """
    report_path = folder / "build_report.json"
    try:
        report = json.loads(report_path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        return f"its build_report.json cannot be read ({e.__class__.__name__})"
    if report.get("variant") != feet:
        return f"it holds the '{report.get('variant')}' variant, not '{feet}'"
    if report.get("format") != C.BUILD_FORMAT:
        return (
            f"it was built by an older footforge (build format {report.get('format')}, this one needs "
            f"{C.BUILD_FORMAT}: {C.BUILD_FORMAT_NEEDS})"
        )
    for name, entry in report.get("inputs", {}).items():
        path = Path(entry.get("path", ""))
        if entry.get("sha256") and path.is_file() and _sha256(path) != entry["sha256"]:
            return f"its input '{name}' ({path}) changed since it was built"
    return None


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _shank_tubes_as_capsules(spec: mujoco.MjSpec) -> None:
    """Each shank's colliding tube (a cylinder longer than its diameter) becomes a capsule of the
    same radius and the same extent along its axis, which MJX collides with heightfields (it
    cannot collide cylinders with them). OmniIsaacGymEnvs' AnymalTerrain collides the whole robot
    with the terrain; with this, shanks stop at stair risers instead of passing through them."""
    for body in spec.bodies:
        if not body.name.endswith("_SHANK"):
            continue
        for geom in body.geoms:
            radius, half_length = geom.size[0], geom.size[1]
            if (
                geom.type == mujoco.mjtGeom.mjGEOM_CYLINDER
                and (geom.contype or geom.conaffinity)
                and half_length > radius
            ):
                geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
                geom.size = [radius, half_length - radius, 0.0]


def load_robot(config: EnvConfig, terrain=None, *, for_mjx: bool = True) -> Robot:
    """The build's scene, set up for MJX as described in the module docstring.

    With a `terrain` (footforge.envs.terrain.Terrain) its heightfield replaces the floor plane,
    under the same geom name. MJX collides heightfields with spheres, capsules, boxes and meshes
    only, and a heightfield costs one prism test per sample under a geom's bounding sphere: the
    feet (small spheres or boxes) keep their collisions, the shank tubes collide as capsules
    (_shank_tubes_as_capsules). On either ground the base's and thighs' collisions (cylinders,
    a 0.6 m box) are switched off for MJX and their ground contact is measured geometrically
    instead (LocomotionEnv.contact_flags). for_mjx=False keeps the model's own geoms, for MuJoCo
    on the CPU.
    """
    check_contact_model(config, on_heightfield=terrain is not None)
    folder = ensure_built(config)
    if terrain is None:
        model = mujoco.MjModel.from_xml_path(str(folder / "scene.xml"))
    else:
        model = _scene_spec(folder, config, terrain, for_mjx).compile()
    _set_physics_options(model, config, on_heightfield=terrain is not None)
    category = np.zeros(model.ngeom, np.int32)
    body_names = [model.body(b).name for b in range(model.nbody)]
    for g in range(model.ngeom):
        if not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        body = body_names[model.geom_bodyid[g]]
        if g == model.geom(FLOOR_GEOM).id:
            continue
        if body == C.BASE_BODY:
            category[g] = GEOM_BASE
        elif "_foot/" in body or (body.endswith("_SHANK") and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE):
            category[g] = GEOM_FOOT + C.LEGS.index(body.split("_")[0])
        elif body.endswith("_THIGH"):
            category[g] = GEOM_THIGH + C.LEGS.index(body.split("_")[0])
        elif body.endswith("_SHANK") and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            category[g] = GEOM_SHANK + C.LEGS.index(body.split("_")[0])
        # Hips and shank tubes: no task needs them to touch the ground. In MJX the base and
        # thighs are checked geometrically (module docstring).
        if category[g] == GEOM_NONE or (for_mjx and category[g] < GEOM_FOOT):
            model.geom_contype[g] = model.geom_conaffinity[g] = 0
    # The C engine's model (under EnvConfig.physics 'mujoco'), or the CPU runner's (for_mjx=False,
    # footforge.envs.engine_mujoco.CpuRobots), each with the sensors it reads.
    engine_model = (
        _with_engine_sensors(model, folder, config, terrain, category, for_mjx)
        if config.physics == "mujoco" or not for_mjx
        else None
    )
    joints = [model.joint(n) for n in C.ACTUATED_JOINTS]
    actuators = np.array([model.actuator(n).id for n in C.ACTUATED_JOINTS])
    passive = [
        model.joint(j).name
        for j in range(model.njnt)
        if "_foot/" in model.joint(j).name and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    ]
    passive.sort(key=lambda n: (C.LEGS.index(n.split("_")[0]), n))
    stand_qpos = model.key(
        "stand" if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "stand") >= 0 else "home"
    ).qpos.copy()
    derived_on_spheres = config.heightfield_soles == "spheres" and foot_variant(config.feet).derived
    if terrain is not None and derived_on_spheres:  # their own rest on the sole spheres
        on_spheres = _stand_on_sole_spheres(folder, config)
        stand_qpos = stand_qpos if on_spheres is None else on_spheres
    return Robot(
        model=model,
        home_qpos=model.key("home").qpos.copy(),
        stand_qpos=stand_qpos,
        actuated_qpos=np.array([j.qposadr[0] for j in joints]),
        actuated_dof=np.array([j.dofadr[0] for j in joints]),
        actuator_ids=actuators,
        default_q=np.array([C.DEFAULT_JOINT_ANGLES_RAD[n] for n in C.ACTUATED_JOINTS]),
        q_limits=np.array([j.range for j in joints]),
        haa=np.array([i for i, n in enumerate(C.ACTUATED_JOINTS) if n.endswith("HAA")]),
        passive_qpos=np.array([model.joint(n).qposadr[0] for n in passive], int),
        passive_dof=np.array([model.joint(n).dofadr[0] for n in passive], int),
        passive_names=tuple(passive),
        geom_category=category,
        floor_geom=model.geom(FLOOR_GEOM).id,
        foot_sites=np.array(foot_sites(model)),
        engine_model=engine_model,
    )


def _scene_spec(folder: Path, config: EnvConfig, terrain, for_mjx: bool) -> mujoco.MjSpec:
    """The build's scene as a spec; with a terrain, its heightfield in place of the floor plane."""
    spec = mujoco.MjSpec.from_file(str(folder / "scene.xml"))
    if terrain is not None:
        from footforge.envs.terrain import add_to_spec

        spec.delete(spec.geom(FLOOR_GEOM))
        add_to_spec(spec, terrain, name=FLOOR_GEOM)
        if for_mjx and config.shank_collisions:
            _shank_tubes_as_capsules(spec)
        # the derived feet's sole boxes only
        if config.heightfield_soles == "spheres" and foot_variant(config.feet).derived:
            _sole_boxes_as_spheres(spec, config.heightfield_sole_grid, config.heightfield_sole_radius_m)
    return spec


def _stand_on_sole_spheres(folder: Path, config: EnvConfig) -> np.ndarray | None:
    """The `stand` pose (footforge.rest) of the build in `folder` with its sole boxes as
    EnvConfig.heightfield_soles' spheres, on the scene's flat floor; None where no sole box is
    replaced (ball feet). The build's `stand` is the rest on its boxes: the spheres, inset from the
    box's edges, hold the loaded soles at other angles, and a robot started from the boxes' rest on
    them is not at rest (measured 2026-11-28: one AOF spawn of eight on rough level 0 kicked a foot
    up 12 cm in the first 0.1 s and slid 20 mm; from this pose 3.3 mm, as the others)."""
    scene = folder / "scene.xml"
    return _stand_on_sole_spheres_cached(
        str(scene),
        scene.stat().st_mtime_ns,
        tuple(config.heightfield_sole_grid),
        float(config.heightfield_sole_radius_m),
    )


@functools.lru_cache(maxsize=8)
def _stand_on_sole_spheres_cached(scene: str, mtime_ns: int, grid: tuple[int, int], radius_m: float):
    from footforge.rest import NoRest, rest_pose

    spec = mujoco.MjSpec.from_file(scene)
    if not _sole_boxes_as_spheres(spec, grid, radius_m):
        return None
    try:
        qpos, _ = rest_pose(spec.compile())
    except NoRest as e:
        raise InputError(
            f"the robot on its sole spheres (heightfield_sole_grid {grid}, radius {radius_m} m) did "
            f"not come to rest on flat ground ({e})",
            file=scene,
            fix="set heightfield_soles to 'box', or another grid or radius",
        ) from None
    return qpos


_SOLE_GEOM_ATTRIBUTES = (
    "contype",
    "conaffinity",
    "group",
    "friction",
    "solmix",
    "solref",
    "solimp",
    "condim",
    "priority",
    "margin",
    "gap",
)
"""What a sole sphere takes over from the box it stands in for."""


def _sole_boxes_as_spheres(spec: mujoco.MjSpec, grid: Sequence[int], radius: float) -> int:
    """Each colliding sole box of the derived feet becomes a grid of spheres on its bottom face
    (EnvConfig.heightfield_soles): the same friction and contact parameters, no mass (the bodies'
    inertials are explicit), in both engines' models, so a heightfield is collided by each engine's
    sphere-prism test, which agree. `grid`, `radius`: EnvConfig.heightfield_sole_grid and
    heightfield_sole_radius_m. Returns the number of boxes replaced."""
    from footforge.geometry import sole_primitives

    grid = tuple(grid)
    if len(grid) != 2 or min(grid) < 1 or not radius > 0:
        raise InputError(
            f"heightfield_sole_grid {grid} and heightfield_sole_radius_m {radius}: give two counts of at "
            "least 1 and a positive radius",
            fix="e.g. heightfield_sole_grid=(3, 2), heightfield_sole_radius_m=0.008",
        )
    replaced = 0
    for body in spec.bodies:
        if "_foot/sole" not in body.name:
            continue
        for geom in list(body.geoms):
            if geom.type != mujoco.mjtGeom.mjGEOM_BOX or not (geom.contype or geom.conaffinity):
                continue
            if not np.allclose(geom.quat, [1.0, 0.0, 0.0, 0.0]):  # the build places sole boxes unrotated
                raise InputError(
                    f"the sole box {geom.name} is rotated in its body; heightfield_soles 'spheres' "
                    f"places spheres on an unrotated box",
                    fix="set heightfield_soles to 'box'",
                )
            if radius > min(geom.size[:2]):
                raise InputError(
                    f"heightfield_sole_radius_m {radius} is wider than the sole box {geom.name} (half "
                    f"sizes {geom.size[0]:.4f} x {geom.size[1]:.4f} m)",
                    fix=f"give at most {min(geom.size[:2]):.4f}",
                )
            for i, shape in enumerate(
                sole_primitives(np.array(geom.pos), np.array(geom.size), "spheres", grid, radius)
            ):
                sphere = body.add_geom(
                    name=f"{geom.name}_sphere{i}",
                    type=mujoco.mjtGeom.mjGEOM_SPHERE,
                    size=[shape["size"][0], 0.0, 0.0],
                    pos=shape["pos"],
                    mass=0.0,
                )
                for name in _SOLE_GEOM_ATTRIBUTES:
                    setattr(sphere, name, getattr(geom, name))
            spec.delete(geom)
            replaced += 1
    return replaced


def _set_physics_options(model: mujoco.MjModel, config: EnvConfig, *, on_heightfield: bool) -> None:
    """The step and solver iterations of `config`, and the contact settings its contact model takes
    on its feet, precision and ground (envs.contact_physics), in place; a setting the row leaves
    None keeps the build's."""
    model.opt.timestep = config.sim_dt
    model.opt.iterations = config.solver_iterations
    model.opt.ls_iterations = config.solver_ls_iterations
    row = resolve(config.contact_model, config.feet, config.float64_physics, on_heightfield)
    if row.cone is not None:
        model.opt.cone = getattr(mujoco.mjtCone, f"mjCONE_{row.cone.upper()}")
    if row.impratio is not None:
        model.opt.impratio = row.impratio
    if row.solimp is not None:
        model.geom_solimp[:, :3] = row.solimp
    if row.solref is not None:  # every geom alike, so MuJoCo's mixing of two geoms' solref changes nothing
        model.geom_solref[:] = row.solref
    if row.integrator is not None:
        model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{row.integrator.upper()}")


def _with_engine_sensors(
    model: mujoco.MjModel, folder: Path, config: EnvConfig, terrain, category: np.ndarray, for_mjx: bool
) -> mujoco.MjModel:
    """`model` compiled again with the sensors the C engine reads (engine_mujoco.add_sensors), its
    physics settings and colliders as in `model`; for the CPU runner (not for_mjx, where the base
    and thighs collide) also their ground contacts and any closure residuals. Sensors change no
    other index or quantity."""
    from footforge.envs.engine_mujoco import add_sensors

    spec = _scene_spec(folder, config, terrain, for_mjx=for_mjx)
    probed = (category == GEOM_BASE) | ((category >= GEOM_THIGH) & (category < GEOM_THIGH + 4))
    bodies = np.unique(model.geom_bodyid[probed])
    add_sensors(
        spec,
        model,
        [np.flatnonzero(category == GEOM_FOOT + i) for i in range(4)],
        model.geom(FLOOR_GEOM).id,
        probe_bodies=bodies,
        foot_sites=foot_sites(model),
        ground_bodies=() if for_mjx else bodies,
    )
    engine_model = spec.compile()
    _set_physics_options(engine_model, config, on_heightfield=terrain is not None)
    engine_model.geom_contype[:] = model.geom_contype
    engine_model.geom_conaffinity[:] = model.geom_conaffinity
    return engine_model


def fit_heightfield_subgrids(mjx_model, model: mujoco.MjModel):
    """`mjx_model` (mjx.put_model(model), the "jax" implementation) with each box's heightfield
    subgrid sized to what MJX's box-heightfield collision can reach, no larger.

    MJX tests a box against the terrain prisms of a fixed subgrid of n x n cells, n =
    ceil(2 r / cell) + 1 with r the box's bounding-sphere radius (ModelJAX.geom_rbound_hfield,
    geom_rbound by default), but starts that subgrid at the box's centre minus its largest
    half-size a (collision_convex.hfield_convex), not minus r. From that start, n - 1 >= (a + r) /
    cell cells already reach past the box's far side in any orientation, so r_fit = (a + r) / 2
    gives the same cells the box can touch. On the 0.1 m terrain this takes AOF's back sole box
    (a 37.6 mm, r 50.013 mm: 13 um over one cell's 50 mm) from 3 x 3 cells (18 prisms) to the 2 x 2
    (8 prisms) of its front box (AOF's collision stage, timed alone for 128 robots: 170 -> 97 ms,
    benchmarks/step_profile.py); every other footforge geom keeps its subgrid. The near side is
    MJX's own: a yawed box's corner can reach up to r - a beyond the start, with or without this.
    Spheres and capsules start at their own bound and keep it."""
    from footforge.envs import mjx_private

    fitted = mjx_private.heightfield_bounds(mjx_model)  # mujoco-mjx 3.17: a static numpy field
    boxes = model.geom_type == mujoco.mjtGeom.mjGEOM_BOX
    fitted[boxes] = (model.geom_size[boxes].max(axis=1) + model.geom_rbound[boxes]) / 2
    return mjx_private.with_heightfield_bounds(mjx_model, fitted)


def check_contact_model(config: EnvConfig, *, on_heightfield: bool = False) -> None:
    """Raises InputError where config.contact_model cannot run stably with config's feet, step and
    solver iterations (EnvConfig.contact_model; the limits are envs.contact_physics's), or is unknown."""
    model = config.contact_model
    row = resolve(model, config.feet, config.float64_physics, on_heightfield)
    if row.max_sim_dt_s is not None and config.sim_dt > row.max_sim_dt_s + 1e-12:
        raise InputError(
            f"contact_model '{model}' needs sim_dt <= {row.max_sim_dt_s} s (given "
            f"{config.sim_dt}): at a longer step its friction chatters",
            fix=f"set sim_dt={row.max_sim_dt_s} and decimation="
            f"{int(round(config.policy_dt / row.max_sim_dt_s))}, or contact_model='fast'",
        )
    needed = row.min_iterations
    if needed and (config.solver_iterations < needed[0] or config.solver_ls_iterations < needed[1]):
        precision = "float64" if config.float64_physics else "float32"
        raise InputError(
            f"contact_model '{model}' needs solver_iterations >= {needed[0]} and solver_ls_iterations >= "
            f"{needed[1]} in {precision} physics (given {config.solver_iterations} and "
            f"{config.solver_ls_iterations}): with fewer its stiff friction diverges on {config.feet} feet",
            fix=f"set solver_iterations={needed[0]} and solver_ls_iterations={needed[1]}"
            + (" (envs.with_float64_physics sets them with float64)" if config.float64_physics else "")
            + ", or contact_model='fast'",
        )


def check_mjx_impl(config: EnvConfig) -> None:
    """Raises InputError where config.mjx_impl cannot run here: 'warp' needs MuJoCo Warp
    (mujoco-mjx's warp extra) and JAX on an NVIDIA GPU."""
    if config.mjx_impl == "jax":
        return
    if config.mjx_impl != "warp":
        raise InputError(f"unknown mjx_impl '{config.mjx_impl}'", fix="use jax or warp")
    import importlib.util

    import jax

    if importlib.util.find_spec("warp") is None or importlib.util.find_spec("mujoco_warp") is None:
        raise InputError(
            "mjx_impl 'warp' needs MuJoCo Warp, which is not installed",
            fix="pip install 'mujoco-mjx[warp]' (with the project's constraints) on a machine "
            "with an NVIDIA GPU, or use mjx_impl jax",
        )
    if jax.default_backend() != "gpu":
        raise InputError(
            f"mjx_impl 'warp' runs on NVIDIA GPUs only; JAX's device here is {jax.default_backend()}",
            fix="use mjx_impl jax (--mjx-impl jax) on this machine",
        )


def foot_sites(model: mujoco.MjModel) -> list[int]:
    """Each leg's foot touchdown site (LF, RF, LH, RH): an adaptive foot's or the ball foot's.

    Raises:
      InputError: a leg without one (a model not written by footforge build).
    """
    sites = []
    for leg in C.LEGS:
        names = (f"{C.FOOT_MODEL_NAME.format(leg=leg)}/touchdown", f"{leg}_touchdown")
        found = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n) for n in names]
        if max(found) < 0:
            raise InputError(f"the model has no touchdown site for leg {leg}", fix="rebuild it with footforge build")
        sites.append(max(found))
    return sites
