"""The CPU dry run of the GPU kit (started by scripts/device/dryrun.sh, which documents it)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
# What the GPU machine has (DEVELOPERS' notes on the machine), JAX at its version.
# Pinned to the set that ran scripts/device/ablations.sh's dry run on 2026-11-26 (the GPU
# machine's own versions may differ: KINDS.md of the device tool lists some).
MACHINE_PACKAGES = [
    "jax==0.11.2",
    "jaxlib==0.11.2",
    "flax==0.12.12",
    "optax==0.2.8",
    "orbax-checkpoint==0.12.8",
    "numpy==2.5.5",
    "scipy==1.18.1",
    "matplotlib==3.11.2",
    "tensorboard==2.21.0",
    "onnx==1.23.2",
    "onnxruntime==1.32.0",
    "rich==15.0.0",
    "pyyaml==6.0.4",
]
# Each job compiles Brax PPO anew, about 5 minutes on 2 busy cores: a 9-minute budget would stop
# the first job after its first checkpoint (the budget's estimate of an epoch includes the
# compilation), so the dry run gives each job 30 minutes; tests/test_train.py tests the stop.
MINUTES = ["--minutes", "30"]
TINY = [
    "--num-envs",
    "8",
    "--unroll-length",
    "4",
    "--batch-size",
    "8",
    "--minibatches",
    "1",
    "--eval-envs",
    "4",
    "--checkpoint-every",
    "32",
    "--physics",
    "mjx",
]
"""The flat job, tiny. --physics mjx: on the CPU `auto` would take MuJoCo's C engine, and the dry run
checks the path the GPU takes (MJX)."""
T0 = time.time()


class Failed(Exception):
    pass


def step(name: str, cmd: list[str], **kw) -> subprocess.CompletedProcess:
    t = time.time()
    print(f"dryrun: {name}: {' '.join(map(str, cmd))}", flush=True)
    done = subprocess.run([str(c) for c in cmd], text=True, capture_output=True, **kw)
    print(done.stdout[-3000:] + done.stderr[-3000:], flush=True)
    print(f"dryrun: {name}: exit {done.returncode} in {time.time() - t:.0f} s", flush=True)
    if done.returncode:
        raise Failed(f"{name} exited {done.returncode}")
    return done


def main(argv: list[str]) -> int:
    rough = "--rough" in argv
    argv = [a for a in argv if a != "--rough"]
    work = Path(argv[0]).resolve() if argv else Path(tempfile.mkdtemp(prefix="footforge-dryrun-"))
    work.mkdir(parents=True, exist_ok=True)
    times: dict[str, float] = {}
    summary = {"dryrun": "failed", "workdir": str(work)}
    try:
        t = time.time()
        venv = work / "venv"
        if not (venv / ".complete").is_file():
            shutil.rmtree(venv, ignore_errors=True)
            step("venv", [sys.executable, "-m", "venv", venv])
            step("machine packages", [venv / "bin/python", "-m", "pip", "install", "-q", *MACHINE_PACKAGES])
            (venv / ".complete").write_text("\n".join(MACHINE_PACKAGES))
        python = venv / "bin/python"
        jax_version = step("jax", [python, "-c", "import jax; print(jax.__version__)"]).stdout.strip()
        if jax_version != "0.11.2":
            raise Failed(f"the venv has jax {jax_version}, not 0.11.2")
        times["venv_s"] = time.time() - t

        t = time.time()
        kit = Path(os.environ.get("KIT", REPO / ".kit")).resolve()
        if not (kit / "wheels").is_dir():
            env = dict(os.environ, PYTHON=os.environ.get("PREPARE_PYTHON", "python3"))
            step("prepare", [REPO / "scripts/device/prepare.sh", kit], env=env)
        repo = work / "repo"
        shutil.rmtree(repo, ignore_errors=True)
        repo.mkdir()
        files = subprocess.run(
            ["git", "-C", REPO, "ls-files", "-z", "-co", "--exclude-standard"], capture_output=True, check=True
        ).stdout.split(b"\0")
        for name in filter(None, (f.decode() for f in files)):
            if (REPO / name).is_file():
                (repo / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(REPO / name, repo / name)
        shutil.copytree(kit, repo / ".kit")
        times["copy_s"] = time.time() - t

        # As on the machine: run.sh installs the wheels with pip --target and runs the job.
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "OUT")}
        env |= {"PYTHON": str(python), "KIT_SITE": str(work / "site"), "JAX_PLATFORMS": "cpu"}
        shutil.rmtree(work / "site", ignore_errors=True)
        run_sh = repo / "scripts/device/run.sh"
        results = [work / f"results{i}" for i in (1, 2, 3)]
        for r in results:
            shutil.rmtree(r, ignore_errors=True)

        if rough:
            summary |= rough_campaign(work, repo, env)
            return 0

        t = time.time()
        step(
            "train",
            [run_sh, *MINUTES, "--results", results[0], "train-flat", "ball", "--", *TINY, "--timesteps", "64"],
            cwd=repo,
            env=env,
        )
        first = check(results[0], "train-flat", min_step=64)
        times["train_s"] = time.time() - t

        t = time.time()
        shutil.rmtree(repo / "runs")  # a fresh machine: only the tarball comes back
        step(
            "resume",
            [
                run_sh,
                *MINUTES,
                "--results",
                results[1],
                "--resume",
                results[0] / "flat_ball_B.tar.gz",
                "train-flat",
                "ball",
                "--",
                *TINY,
                "--timesteps",
                "128",
            ],
            cwd=repo,
            env=env,
        )
        second = check(results[1], "train-flat", min_step=128)
        progress = json.loads(extract(results[1] / "flat_ball_B.tar.gz", "flat_ball_B/progress.json"))
        if progress.get("resumes") != 1:
            raise Failed(f"the second job did not resume from the first's checkpoint: {progress}")
        times["resume_s"] = time.time() - t

        t = time.time()
        shutil.rmtree(repo / "runs")
        step(
            "evaluate",
            [
                run_sh,
                *MINUTES,
                "--results",
                results[2],
                "--resume",
                results[1] / "flat_ball_B.tar.gz",
                "evaluate",
                "flat_ball_B",
                "--",
                "--num-envs",
                "2",
                "--seconds",
                "0.4",
                "--physics",
                "mjx",
            ],
            cwd=repo,
            env=env,
        )
        third = check(results[2], "evaluate", min_step=128)
        indices = third["evaluation"][0]["indices"]
        if "flat_ball_B/evaluation/metrics.json" not in tar_names(results[2] / "flat_ball_B.tar.gz"):
            raise Failed("the evaluation is not in the results tarball")
        times["evaluate_s"] = time.time() - t
        summary |= {
            "dryrun": "ok",
            "jax": third["jax"].get("version"),
            "steps": [first["global_step"], second["global_step"]],
            "forward_error": indices.get("lin_vel_x_error", {}).get("mean") if isinstance(indices, dict) else None,
            "tarball_kib": round((results[1] / "flat_ball_B.tar.gz").stat().st_size / 1024),
        }
        return 0
    except Failed as e:
        summary["error"] = str(e)
        return 1
    finally:
        summary |= {k: round(v) for k, v in times.items()} | {"total_s": round(time.time() - T0)}
        print(json.dumps(summary))


ROUGH_ITERATION = 64 * 4 * 24
"""Steps of one PPO iteration of the rough `cpu` preset's batch (128 robots x 24-step unrolls, 4
minibatches of 64 trajectories: 6,144), the unit the dry run's rough runs advance by."""


ROUGH_JOBS = (("aof", "B", None), ("aof", "BH", None))
"""The prepared rough call's jobs (docs/training.md): feet, policy type, and the committed run each resumes
(None: begun under the rough `cpu` preset)."""


def rough_campaign(work: Path, repo: Path, env: dict) -> dict:
    """The prepared rough call (docs/training.md) through campaign.sh --cpu, shortened: its jobs (ROUGH_JOBS;
    a committed run resumed, or a run begun under the rough `cpu` preset) for two PPO iterations, side by
    side on the C engine; then, as on a new machine (no runs/, no cache), both resumed from their tarballs
    for one more. Returns the figures for the summary line."""
    if " " in str(work):
        raise Failed(f"--rough needs a WORKDIR without spaces (campaign.sh splits its jobs at spaces): {work}")
    campaign = repo / "scripts/device/campaign.sh"
    start = {
        (feet, policy): json.loads((repo / committed / "progress.json").read_text())["global_step"] if committed else 0
        for feet, policy, committed in ROUGH_JOBS
    }
    figures = {}
    s: dict = {}
    for call, iterations in ((1, 2), (2, 3)):
        t = time.time()
        specs = []
        for feet, policy, committed in ROUGH_JOBS:
            run = f"rough_{feet}_{policy}"
            steps = start[feet, policy] + iterations * ROUGH_ITERATION
            if call == 2:
                source = work / "campaign1" / f"train-{run}" / f"{run}.tar.gz"
            else:
                source = repo / committed if committed else None
            options = "--no-evaluations" + (" --preset cpu" if source is None else "")
            shorten = " --shorten" if committed else ""  # the committed run's total is 30 M steps
            resume = f"--resume {source} " if source else ""
            specs.append(f"{resume}train-rough {feet} {policy} -- {options} --timesteps {steps}{shorten}")
        out = work / f"rough_results{call}"
        shutil.rmtree(out, ignore_errors=True)
        # A fresh machine: only the tarballs come back, and the compilation cache where it is carried
        # (unpacked into .kit-cache/, as docs/training.md says).
        shutil.rmtree(repo / "runs", ignore_errors=True)
        shutil.rmtree(repo / ".kit-cache", ignore_errors=True)
        if call == 2 and (work / "rough_results1" / "jax_cache.tar.gz").is_file():
            with tarfile.open(work / "rough_results1" / "jax_cache.tar.gz") as tar:
                tar.extractall(repo / ".kit-cache", filter="data")
        cmd = [campaign, "--cpu", "--results", out, *MINUTES, *specs]
        done = step(f"rough campaign {call}", cmd, cwd=repo, env=env)
        if shutil.which("taskset") and done.stdout.count("taskset -c ") != 2:
            raise Failed("campaign.sh --cpu did not pin each job to its cores (taskset -c)")
        unpacked = work / f"campaign{call}"
        shutil.rmtree(unpacked, ignore_errors=True)
        with tarfile.open(out / "campaign.tar.gz") as tar:
            tar.extractall(unpacked, filter="data")
        for feet, policy, committed in ROUGH_JOBS:
            run = f"rough_{feet}_{policy}"
            steps = start[feet, policy] + iterations * ROUGH_ITERATION
            s = check(unpacked / f"train-{run}", f"train-rough {feet} {policy}", min_step=steps, run=run)
            progress = json.loads(extract(unpacked / f"train-{run}" / f"{run}.tar.gz", f"{run}/progress.json"))
            resumes_before = (
                json.loads((repo / committed / "progress.json").read_text()).get("resumes", 0) if committed else 0
            )
            expected = resumes_before + (call if committed else call - 1)
            if progress.get("resumes") != expected:
                raise Failed(
                    f"{run} did not resume as the call says: {progress.get('resumes')} resumes, {expected} expected"
                )
            if progress.get("physics") != "mujoco":
                raise Failed(f"{run} ran on {progress.get('physics')}, not MuJoCo's C engine (campaign.sh --cpu)")
            figures[f"{run}_call{call}_step"] = s["global_step"]
        figures[f"rough_call{call}_s"] = round(time.time() - t)
    return figures | {"dryrun": "ok", "jax": s.get("jax", {}).get("version")}


def check(results: Path, job: str, min_step: int, run: str = "flat_ball_B") -> dict:
    summary_file = results / "summary.json"
    if not summary_file.is_file():
        raise Failed(f"{job}: no summary.json in {results}")
    s = json.loads(summary_file.read_text())
    if s.get("returncode") != 0:
        raise Failed(f"{job}: the job failed: {s}")
    if s.get("forbidden_imported"):
        raise Failed(f"{job}: the training path imported {s['forbidden_imported']}")
    if s.get("global_step", 0) < min_step:
        raise Failed(f"{job}: global step {s.get('global_step')} < {min_step}")
    tarball = results / s.get("tarball", "missing")
    if not tarball.is_file() or tarball.stat().st_size > 16 * 2**20:
        raise Failed(f"{job}: no results tarball under 16 MiB: {tarball}")
    names = tar_names(tarball)
    for needed in ("progress.json", "config.json", "metrics.jsonl", "policy/footforge.json"):
        if f"{run}/{needed}" not in names:
            raise Failed(f"{job}: {needed} missing from {tarball.name}")
    if len(list(results.iterdir())) > 8:
        raise Failed(f"{job}: more than 8 result files")
    return s


def tar_names(tarball: Path) -> set[str]:
    with tarfile.open(tarball) as tar:
        return set(tar.getnames())


def extract(tarball: Path, name: str) -> str:
    with tarfile.open(tarball) as tar:
        return tar.extractfile(name).read().decode()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
