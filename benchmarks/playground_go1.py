"""MuJoCo Playground's Go1 joystick environment (Go1JoystickFlatTerrain, Go1JoystickRoughTerrain)
timed the way env_speed.py times footforge's environments: a batched reset and step (jax.vmap,
jax.jit), compile time (reset plus the first two steps, executed: see measure) and then policy
steps per second over N steps, on whatever JAX device is present; one JSON line when run alone.
A reference point for footforge's figures (env_speed.py --playground): another quadruped's MJX
joystick task at the same batch sizes, in the same process and on the same device.

Optional: needs the `playground` package (import name mujoco_playground), in the bench extra:
pip install -c constraints.txt -e ".[bench]". footforge itself does not depend on it.

The Playground environment as it ships, with two settings of this benchmark:
- impl "jax" (the MJX JAX implementation, as footforge's environments use), where Playground's Go1
  default is "warp" (MuJoCo Warp: needs warp-lang and an NVIDIA GPU); --impl warp asks for it.
- Stand-in visual meshes. The Go1 scenes (go1_mjx_feetonly.xml) read five meshes from MuJoCo
  Menagerie (unitree_go1/assets/{trunk,hip,thigh,thigh_mirror,calf}.stl), which Playground clones
  from GitHub on first use (registry.load -> ensure_menagerie_exists). Nothing is downloaded here:
  where that folder lacks the meshes, a 4-face tetrahedron STL written to a temporary folder
  stands in for each. They are used only by the 13 geoms of class "visual" (contype=0,
  conaffinity=0, group 2), and every body carrying one has an explicit <inertial>, so they enter
  neither the masses nor the contacts. Checked whenever the stand-ins are used (physics_check,
  run before the environment is made; a difference raises): the model with the stand-ins, the model with a
  different stand-in (a 0.3 m box) and the model with the visual geoms and meshes deleted have
  identical body masses (total 12.743448 kg), inertias, centres of mass and colliding geoms
  (type, size, pose, friction, solref, solimp, condim, priority, margin, contype, conaffinity), and
  200 MuJoCo (C) steps from the home keyframe give bit-identical qpos.

Settings of Playground's Go1 joystick (playground 0.2.0): ctrl_dt 0.02 s, sim_dt 0.004 s (5 physics
steps per policy step), Euler, Newton with 1 iteration and 5 line-search iterations, pyramidal
cones; only the four foot spheres collide, with the floor (a plane, or a 256 x 256 heightfield of
20 x 20 m for rough), 1 MJX contact per foot on the plane and 4 on the heightfield. Each result
carries these as read from the model and the MJX data.

Usage: python benchmarks/playground_go1.py [--batches 16 64 256] [--steps 20] [--terrains flat rough]
           [--actions zero random] [--impl jax] [--no-compile-cache]

Keys: <terrain>_b<batch>: {compile_s, policy_steps_per_s, physics_steps_per_s (policy steps x
n_substeps), actions, ctrl_dt, sim_dt, n_substeps, timestep, iterations, ls_iterations, cone, solver,
integrator, impl, contacts_per_foot, meshes ("menagerie" or "stand-in")}; machine, device, jax,
playground (its version), compile_cache.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.metadata
import importlib.util
import json
import platform
import struct
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ENV_NAMES = {"flat": "Go1JoystickFlatTerrain", "rough": "Go1JoystickRoughTerrain"}
XML_TASKS = {"flat": "flat_terrain", "rough": "rough_terrain"}
MESHES = ("trunk", "hip", "thigh", "thigh_mirror", "calf")
INSTALL_HINT = 'pip install -c constraints.txt -e ".[bench]"'
MISSING_MESSAGE = f"MuJoCo Playground (mujoco_playground) is not installed; install the benchmark extra: {INSTALL_HINT}"


def available() -> bool:
    """Whether mujoco_playground can be imported (the optional bench extra)."""
    return importlib.util.find_spec("mujoco_playground") is not None


def version() -> str | None:
    try:
        return importlib.metadata.version("playground")
    except importlib.metadata.PackageNotFoundError:
        return None


def _stl(vertices: np.ndarray, faces: list[tuple[int, int, int]]) -> bytes:
    """A binary STL (normals left 0: MuJoCo computes its own)."""
    out = bytearray(80) + struct.pack("<I", len(faces))
    for face in faces:
        out += struct.pack("<3f", 0.0, 0.0, 0.0)
        for i in face:
            out += struct.pack("<3f", *vertices[i])
        out += b"\0\0"
    return bytes(out)


def _tetrahedron_stl(edge: float = 0.01) -> bytes:
    v = np.array([[0, 0, 0], [edge, 0, 0], [0, edge, 0], [0, 0, edge]], np.float32)
    return _stl(v, [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])


def _box_stl(half: float) -> bytes:
    v = np.array([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)], np.float32)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return _stl(v, [tri for a, b, c, d in quads for tri in ((a, b, c), (a, c, d))])


def _menagerie_has_go1() -> bool:
    from mujoco_playground._src import mjx_env

    assets = mjx_env.MENAGERIE_PATH / "unitree_go1" / "assets"
    return all((assets / f"{name}.stl").exists() for name in MESHES)


def _scene(terrain: str, meshes: dict[str, bytes] | None, strip_visual: bool = False):
    """Playground's Go1 scene (feet-only collisions) compiled by MuJoCo (C), with the given meshes
    (file name -> STL) or, with strip_visual, without its mesh geoms and meshes."""
    import mujoco
    from mujoco_playground._src.locomotion.go1 import base, go1_constants as consts

    assets = base.get_assets()  # Playground's own XML files and textures/heightfield
    files = {k: v for k, v in assets.items() if not k.endswith(".xml")} | (meshes or {})
    include = {k: v for k, v in assets.items() if k.endswith(".xml")}
    spec = mujoco.MjSpec.from_string(consts.task_to_xml(XML_TASKS[terrain]).read_text(), include=include, assets=files)
    if strip_visual:
        for geom in list(spec.geoms):
            if geom.type == mujoco.mjtGeom.mjGEOM_MESH:
                spec.delete(geom)
        for mesh in list(spec.meshes):
            spec.delete(mesh)
    return spec.compile()


def physics_check(terrain: str, steps: int = 200) -> dict:
    """Raises if the stand-in meshes change the physics: compares the model with tetrahedra, with
    0.3 m boxes and without the visual geoms (masses, inertias, colliding geoms, 200 C steps)."""
    import mujoco

    models = {
        "tetrahedra": _scene(terrain, {f"{n}.stl": _tetrahedron_stl() for n in MESHES}),
        "boxes": _scene(terrain, {f"{n}.stl": _box_stl(0.15) for n in MESHES}),
        "no_visual": _scene(terrain, None, strip_visual=True),
    }

    def colliding(m):
        rows = []
        for g in range(m.ngeom):
            if m.geom_contype[g] or m.geom_conaffinity[g]:
                rows.append(
                    (
                        m.body(m.geom_bodyid[g]).name,
                        m.geom(g).name,
                        int(m.geom_type[g]),
                        *m.geom_size[g],
                        *m.geom_pos[g],
                        *m.geom_quat[g],
                        *m.geom_friction[g],
                        *m.geom_solref[g],
                        *m.geom_solimp[g],
                        int(m.geom_condim[g]),
                        int(m.geom_priority[g]),
                        m.geom_margin[g],
                        m.geom_gap[g],
                        int(m.geom_contype[g]),
                        int(m.geom_conaffinity[g]),
                    )
                )
        return rows

    def trajectory(m):
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
        for _ in range(steps):
            mujoco.mj_step(m, d)
        return d.qpos.copy()

    ref = models["tetrahedra"]
    for name, m in models.items():
        same = (
            np.array_equal(m.body_mass, ref.body_mass)
            and np.array_equal(m.body_inertia, ref.body_inertia)
            and np.array_equal(m.body_ipos, ref.body_ipos)
            and np.array_equal(m.body_iquat, ref.body_iquat)
            and colliding(m) == colliding(ref)
            and np.array_equal(trajectory(m), trajectory(ref))
        )
        if not same:
            raise RuntimeError(f"Go1 {terrain}: the stand-in meshes change the physics ({name} differs)")
    return {
        "total_mass_kg": round(float(ref.body_subtreemass[0]), 6),
        "colliding_geoms": len(colliding(ref)),
        "visual_mesh_geoms": int(np.sum(ref.geom_type == mujoco.mjtGeom.mjGEOM_MESH)),
    }


@contextlib.contextmanager
def _menagerie_stand_in():
    """Points Playground's Menagerie folder at a temporary one holding stand-in Go1 meshes (so
    registry.load neither clones Menagerie nor misses a file); restored afterwards."""
    from mujoco_playground._src import mjx_env

    saved = mjx_env.MENAGERIE_PATH
    with tempfile.TemporaryDirectory(prefix="go1_stand_in_") as tmp:
        assets = Path(tmp) / "mujoco_menagerie" / "unitree_go1" / "assets"
        assets.mkdir(parents=True)
        for name in MESHES:
            (assets / f"{name}.stl").write_bytes(_tetrahedron_stl())
        mjx_env.MENAGERIE_PATH = type(saved)(assets.parent.parent)
        try:
            yield
        finally:
            mjx_env.MENAGERIE_PATH = saved


def make_env(terrain: str, impl: str = "jax"):
    """Playground's Go1 joystick env for 'flat' or 'rough' and where its meshes came from."""
    from mujoco_playground import registry

    if _menagerie_has_go1():
        return registry.load(ENV_NAMES[terrain], config_overrides={"impl": impl}), "menagerie"
    physics_check(terrain)
    with _menagerie_stand_in():
        return registry.load(ENV_NAMES[terrain], config_overrides={"impl": impl}), "stand-in"


def _name(value) -> str:
    return value.name.split("_", 1)[1].lower()  # mjCONE_PYRAMIDAL -> pyramidal


def settings(env, state=None) -> dict:
    """The environment's time steps and solver, as read from its model, and (from a batched state
    of the "jax" implementation) the MJX contact slots per foot sphere - floor pair."""
    import mujoco

    m = env.mj_model
    contacts = None
    if state is not None and env.mjx_model.impl.value == "jax":
        geom = np.asarray(state.data._impl.contact.geom)[0]  # the first environment's (ncon, 2)
        floor = m.geom("floor").id
        per_foot = {
            int(np.sum(((geom[:, 0] == g) & (geom[:, 1] == floor)) | ((geom[:, 0] == floor) & (geom[:, 1] == g))))
            for g in (m.geom(foot).id for foot in ("FR", "FL", "RR", "RL"))
        }
        contacts = per_foot.pop() if len(per_foot) == 1 else sorted(per_foot)
    return {
        "ctrl_dt": float(env.dt),
        "sim_dt": float(env.sim_dt),
        "n_substeps": int(env.n_substeps),
        "timestep": float(m.opt.timestep),
        "iterations": int(m.opt.iterations),
        "ls_iterations": int(m.opt.ls_iterations),
        "cone": _name(mujoco.mjtCone(m.opt.cone)),
        "solver": _name(mujoco.mjtSolver(m.opt.solver)),
        "integrator": _name(mujoco.mjtIntegrator(m.opt.integrator)),
        "impl": env.mjx_model.impl.value,
        "contacts_per_foot": contacts,
    }


def measure(
    terrain: str, batch: int, steps: int, actions: str = "zero", seed: int = 0, impl: str = "jax", env=None
) -> dict:
    """Compile time and throughput of Playground's Go1 joystick ('flat' or 'rough') at a batch size:
    compile_s (reset and the first two steps, compiled and run), then `steps` policy steps timed
    after them; zero actions, or uniform random ones in [-1, 1] drawn once with `seed`.

    Two warm-up steps, where env_speed.py's own environments need one: Playground's reset returns
    metrics['reward/termination'] strongly typed and its step returns it weakly typed, so jax.jit
    compiles the step a second time on its second call (checked: no compilation in the timed loop)."""
    import jax
    import jax.numpy as jp

    meshes = None
    if env is None:
        env, meshes = make_env(terrain, impl)
    reset = jax.jit(jax.vmap(env.reset))
    step = jax.jit(jax.vmap(env.step))
    keys = jax.random.split(jax.random.PRNGKey(seed), batch)
    if actions == "zero":
        act = jp.zeros((batch, env.action_size))
    else:
        act = jax.random.uniform(jax.random.PRNGKey(seed + 1), (batch, env.action_size), minval=-1.0, maxval=1.0)
    t0 = time.perf_counter()
    state = reset(keys)
    for _ in range(2):
        state = step(state, act)
    jax.block_until_ready(state.obs)
    compile_s = time.perf_counter() - t0
    compiled = step._cache_size()
    t0 = time.perf_counter()
    for _ in range(steps):
        state = step(state, act)
    jax.block_until_ready(state.obs)
    rate = batch * steps / (time.perf_counter() - t0)
    if step._cache_size() != compiled:
        raise RuntimeError("Playground Go1: the step compiled again inside the timed loop")
    result = {
        "compile_s": round(compile_s, 1),
        "policy_steps_per_s": round(rate, 1),
        "physics_steps_per_s": round(rate * env.n_substeps, 1),
        "actions": actions,
    }
    if meshes:
        result["meshes"] = meshes
    return result | settings(env, state)


def measure_all(terrains, batches, steps: int, actions: str = "zero", impl: str = "jax") -> dict:
    """{'<terrain>_b<batch>': measure(...)} for each terrain and batch size, one env per terrain."""
    figures = {}
    for terrain in terrains:
        env, meshes = make_env(terrain, impl)
        for batch in batches:
            figures[f"{terrain}_b{batch}"] = measure(terrain, batch, steps, actions, impl=impl, env=env) | {
                "meshes": meshes
            }
    return figures


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--batches", type=int, nargs="+", default=[16, 64, 256])
    p.add_argument("--steps", type=int, default=20, help="policy steps timed per batch size")
    p.add_argument("--terrains", nargs="+", default=["flat", "rough"], choices=list(ENV_NAMES))
    p.add_argument("--actions", default="zero", choices=["zero", "random"])
    p.add_argument(
        "--impl", default="jax", choices=["jax", "warp"], help="MJX implementation (Playground's default: warp)"
    )
    p.add_argument(
        "--no-compile-cache",
        action="store_true",
        help="measure cold compilation: without JAX's persistent cache (footforge/rl/compile_cache.py)",
    )
    args = p.parse_args(argv)
    if not available():
        print(MISSING_MESSAGE, file=sys.stderr)
        return 2
    import jax

    from footforge.rl import compile_cache

    cache = compile_cache.enable(not args.no_compile_cache)
    figures = {
        "machine": platform.platform(),
        "device": str(jax.devices()[0]),
        "jax": jax.__version__,
        "playground": version(),
        "compile_cache": str(cache) if cache else None,
    }
    figures |= measure_all(args.terrains, args.batches, args.steps, args.actions, args.impl)
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
