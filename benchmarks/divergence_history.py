"""Why two physics settings are what they are: the divergences they prevent, reproduced. Builds
AFF and AOF into a temporary folder and drives them with an untrained policy's random actions
(footforge.envs.stability: CPU MuJoCo on the environment's own model); one JSON line: per
setting, the robots that diverged and when.

- `aff_stance_float64`: why float64 `stance` needs 16 Newton iterations on AFF feet
  (its row in envs.contact_physics). At 16/16 no robot diverged; with the refusal
  lifted, at 8/16, 3 to 7 of 8 robots did (7 of 8 within 0.35 s with every foot box colliding,
  3 of 8 within 8 s with the sole alone). Was tests/test_envs.py's
  test_the_adaptive_feet_s_stance_diverges_under_actions_with_fewer_iterations.
- `aof_armature`: why `fast` steps AOF at the baselines' 5 ms. With the passive joints' old
  armature of 1e-5 kg m^2 the physics diverged at 5 ms (23 of 32 robots in 10 s; 29-37 % of the
  H100 campaign's AOF episodes), so the adaptive feet stepped at 2.5 ms until 2026-11-25; with
  the parameter file's 1e-3 none diverged at 5 ms or 2.5 ms. Was tests/test_envs.py's
  test_adaptive_feet_train_at_a_physics_step_that_survives_a_policy_s_actions (3 or more of 12
  robots diverging with the old armature).

Chaotic: which robots diverge changes with the last bit of the arithmetic (another CPU, another
library build); compare counts, not robots.

Usage: python benchmarks/divergence_history.py [--experiments aff_stance_float64 aof_armature]
           [--robots 16] [--seconds 8] [--seed 0]
"""

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from footforge import envs
from footforge.build import BuildOptions, build
from footforge.envs import contact_physics
from footforge.envs.config import EnvConfig
from footforge.envs.stability import divergence_times
from footforge.inputs.params import default_params_path


def _figures(config: EnvConfig, robots: int, seconds: float, seed: int) -> dict:
    t0 = time.perf_counter()
    times = divergence_times(config, robots, seconds, seed)
    hit = [t for t in times if t is not None]
    wall = round(time.perf_counter() - t0, 1)
    return {"diverged": len(hit), "robots": robots, "seconds": seconds, "times_s": hit, "wall_s": wall}


def aff_stance_float64(tmp: Path, robots: int, seconds: float, seed: int) -> dict:
    build(BuildOptions(variant="aff", out_dir=tmp / "aff", formats=("mjcf",)))
    float32 = envs.with_contact_model(EnvConfig(feet="aff", build_dir=str(tmp / "aff")), "stance")
    stance = envs.with_float64_physics(float32)
    figures = {"16_16": _figures(stance, robots, seconds, seed)}
    rows = contact_physics.CONTACT_PHYSICS
    row = contact_physics.resolve("stance", "aff", float64_physics=True, on_heightfield=False)
    try:  # the refusal lifted, to show what it prevents: a row for AFF alone in front (the first match wins)
        contact_physics.CONTACT_PHYSICS = (replace(row, feet=("aff",), min_iterations=(8, 16)), *rows)
        figures["8_16"] = _figures(replace(stance, solver_iterations=8), robots, seconds, seed)
    finally:
        contact_physics.CONTACT_PHYSICS = rows
    return figures


def aof_armature(tmp: Path, robots: int, seconds: float, seed: int) -> dict:
    build(BuildOptions(variant="aof", out_dir=tmp / "aof", formats=("mjcf",)))
    text = default_params_path().read_text()
    old = tmp / "params_armature_1e-5.yaml"
    old.write_text(text.replace("armature: 1.0e-3", "armature: 1.0e-5"))
    build(BuildOptions(variant="aof", out_dir=tmp / "aof_1e-5", params=old, formats=("mjcf",)))
    at_5ms = replace(envs.default_config("flat", "aof", "B", "fast"), build_dir=str(tmp / "aof"))
    at_2_5ms = replace(at_5ms, sim_dt=0.0025, decimation=8)
    return {
        "armature_1e-3_5ms": _figures(at_5ms, robots, seconds, seed),
        "armature_1e-3_2.5ms": _figures(at_2_5ms, robots, seconds, seed),
        "armature_1e-5_5ms": _figures(replace(at_5ms, build_dir=str(tmp / "aof_1e-5")), robots, seconds, seed),
        "passive_joints_at_1e-3_in_the_parameter_file": text.count("armature: 1.0e-3"),
    }


EXPERIMENTS = {"aff_stance_float64": aff_stance_float64, "aof_armature": aof_armature}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--experiments", nargs="+", choices=list(EXPERIMENTS), default=list(EXPERIMENTS))
    p.add_argument("--robots", type=int, default=16)
    p.add_argument("--seconds", type=float, default=8.0)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    figures: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.experiments:
            figures[name] = EXPERIMENTS[name](Path(tmp), args.robots, args.seconds, args.seed)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
