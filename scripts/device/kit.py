"""The jobs of the offline GPU kit; started by scripts/device/run.sh (which installs the wheels and
sets PYTHONPATH and the XLA options first). Run from the repository root.

    run.sh [options] bench [FEET...] [-- env_speed.py options]
        MJX environment steps/s (benchmarks/env_speed.py, flat and rough, --batches 4096 8192 by
        default) and PPO training steps/s (a flat-ball training of --ppo-envs robots for the rest of
        the budget; Brax's training/sps): bench.json.
    run.sh [options] train-flat FEET [POLICY] [-- train_flat.py options]
    run.sh [options] train-rough FEET POLICY [-- train_rough.py options]
        Trains into RUNS/flat_FEET_POLICY (rough_...), resuming when that folder has checkpoints
        (bring it back with --resume RESULTS.tar.gz), and stops at the last checkpoint that fits
        the budget (--minutes).
    run.sh [options] evaluate RUN [FEET...] [-- evaluate.py options]
        pipelines/evaluate.py on RUNS/RUN/policy (on FEET, default its own), into RUNS/RUN/evaluation.

Every job writes into --results: summary.json (job, run, steps, whether training is complete,
timings, the last metrics, JAX devices), the job's log, and for runs RUN.tar.gz: the run folder
with only its latest checkpoint (under 16 MiB, checked). Exit codes: 0 done, 1 failed, 2 usage.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tarfile
import time
from pathlib import Path

T0 = time.time()
REPO = Path(__file__).resolve().parents[2]
FEET = ("ball", "aff", "aof")
MAX_TARBALL = 16 * 2**20
FORBIDDEN = ("dm_control", "pinocchio", "coacd", "pxr", "xacro")  # build-time packages the GPU machine lacks


class UsageError(Exception):
    pass


def core_share(cpus: list[int], jobs: int, index: int) -> list[int]:
    """The CPUs of job `index` of `jobs` side by side on `cpus`: consecutive, equal shares, the
    first jobs one more where they do not divide; with more jobs than CPUs, one CPU each in turn."""
    if jobs > len(cpus):
        return [cpus[index % len(cpus)]]
    per, extra = divmod(len(cpus), jobs)
    start = index * per + min(index, extra)
    return cpus[start : start + per + (index < extra)]


def main(argv: list[str]) -> int:
    if argv[:1] == ["--core-share"]:  # campaign.sh --cpu: `kit.py --core-share JOBS INDEX` prints a taskset list
        jobs, index = int(argv[1]), int(argv[2])
        print(",".join(str(c) for c in core_share(sorted(os.sched_getaffinity(0)), jobs, index)))
        return 0
    extra: list[str] = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1 :]
    p = argparse.ArgumentParser(
        prog="run.sh",
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__,
    )
    p.add_argument("--kit", type=Path, default=REPO / ".kit", help="the kit (prepare.sh's KITDIR; default .kit)")
    p.add_argument(
        "--results",
        type=Path,
        default=Path(os.environ.get("OUT") or "results"),
        help="folder for the results (default $OUT, else results/)",
    )
    p.add_argument(
        "--minutes",
        type=float,
        default=9.0,
        help="wall-clock budget of the whole job, install excluded (default 9: a 10-minute job)",
    )
    p.add_argument("--runs", type=Path, default=Path("runs"), help="folder of the run folders (default runs/)")
    p.add_argument(
        "--resume",
        type=Path,
        metavar="TARBALL|RUNDIR",
        help="a RUN.tar.gz (or run folder) brought back from an earlier job, unpacked into --runs first",
    )
    p.add_argument("--ppo-envs", type=int, default=4096, help="bench: robots of the PPO throughput run")
    p.add_argument("job", choices=("bench", "train-flat", "train-rough", "evaluate"))
    p.add_argument("names", nargs="*", help="FEET [POLICY] or RUN [FEET...]")
    args = p.parse_args(argv)
    try:
        return run_job(args, extra)
    except UsageError as e:
        print(f"run: error: {e}", file=sys.stderr)
        return 2


def run_job(args, extra: list[str]) -> int:
    if args.minutes <= 0:
        raise UsageError("--minutes must be positive")
    if args.job in ("train-flat", "train-rough") and (not 1 <= len(args.names) <= 2 or args.names[0] not in FEET):
        raise UsageError(f"{args.job} FEET [POLICY]: FEET one of {', '.join(FEET)}")
    if args.job == "evaluate" and not args.names:
        raise UsageError("evaluate RUN [FEET...]")
    if any(
        f not in FEET for f in (args.names[1:] if args.job == "evaluate" else args.names if args.job == "bench" else [])
    ):
        raise UsageError(f"FEET must be among {', '.join(FEET)}")
    results = args.results.resolve()
    results.mkdir(parents=True, exist_ok=True)
    runs = args.runs.resolve()
    runs.mkdir(parents=True, exist_ok=True)
    link_builds(args.kit.resolve())
    deadline = T0 + args.minutes * 60
    log = results / f"{args.job}.log"
    summary: dict = {
        "job": args.job,
        "args": args.names,
        "extra": extra,
        "machine": platform.node(),
        "python": sys.version.split()[0],
    }
    if args.resume:
        summary["resumed_from"] = str(args.resume)
        unpack(args.resume, runs)

    if args.job in ("train-flat", "train-rough"):
        task = args.job.split("-")[1]
        if not 1 <= len(args.names) <= 2 or args.names[0] not in FEET:
            raise UsageError(f"{args.job} FEET [POLICY]: FEET one of {', '.join(FEET)}")
        feet, policy = args.names[0], (args.names[1] if len(args.names) > 1 else "B")
        run = runs / f"{task}_{feet}_{policy}"
        cmd = [
            sys.executable,
            str(REPO / f"pipelines/train_{task}.py"),
            "--feet",
            feet,
            "--policy",
            policy,
            "--out",
            str(run),
        ]
        if (run / "checkpoints").is_dir() and any(p.name.isdigit() for p in (run / "checkpoints").iterdir()):
            cmd.append("--resume")
        elif run.is_dir():  # a run killed before its first checkpoint: training refuses it without --force
            cmd.append("--force")
        reserve = 45.0  # packing the results, and the slack of the estimate of one epoch
        train_s = deadline - time.time() - reserve
        if train_s < 60:
            raise UsageError(f"--minutes {args.minutes:g} leaves {train_s:.0f} s to train")
        cmd += ["--max-minutes", f"{train_s / 60:.3f}"] + extra
        code = call(cmd, log, timeout=deadline - time.time() - 10)
        summary |= {"run": run.name, "returncode": code} | run_state(run)
        # Packed also when the job was killed at its limit: its checkpoints let the next job resume.
        if (run / "policy").is_dir() or summary["global_step"]:
            summary["tarball"] = pack(run, results)
    elif args.job == "evaluate":
        if not args.names:
            raise UsageError("evaluate RUN [FEET...]")
        run = Path(args.names[0]) if Path(args.names[0]).is_dir() else runs / args.names[0]
        if not (run / "policy").is_dir():
            raise UsageError(f"{run} has no policy/ (bring the run with --resume RUN.tar.gz)")
        feet = args.names[1:]
        if any(f not in FEET for f in feet):
            raise UsageError(f"FEET must be among {', '.join(FEET)}")
        cmd = (
            [
                sys.executable,
                str(REPO / "pipelines/evaluate.py"),
                "--policy",
                str(run / "policy"),
                "--out",
                str(run / "evaluation"),
            ]
            + (["--feet", *feet] if feet else [])
            + extra
        )
        code = call(cmd, log, timeout=deadline - time.time() - 20)
        summary |= {"run": run.name, "returncode": code} | run_state(run)
        if code == 0:
            summary["evaluation"] = json.loads((run / "evaluation" / "metrics.json").read_text())
            summary["tarball"] = pack(run, results)
    else:  # bench
        feet = args.names or list(FEET)
        if any(f not in FEET for f in feet):
            raise UsageError(f"FEET must be among {', '.join(FEET)}")
        env_json = results / "env_speed.json"
        cmd = [sys.executable, str(REPO / "benchmarks/env_speed.py"), "--feet", *feet]
        cmd += extra if extra else ["--batches", "4096", "8192", "--tasks", "flat", "rough"]
        with open(env_json, "w") as out:
            code = call(cmd, log, timeout=(deadline - time.time()) * 0.6, stdout=out)
        summary["env_speed_returncode"] = code
        lines = [line for line in env_json.read_text().splitlines() if line.strip().startswith("{")]
        summary["env_speed"] = json.loads(lines[-1]) if lines else None
        # PPO throughput: flat ball with the paper's settings, for what is left of the budget.
        run = runs / "bench_ppo_flat_ball"
        shutil.rmtree(run, ignore_errors=True)
        train_s = deadline - time.time() - 30
        if train_s > 60:
            n = args.ppo_envs
            cmd = [
                sys.executable,
                str(REPO / "pipelines/train_flat.py"),
                "--feet",
                "ball",
                "--out",
                str(run),
                "--num-envs",
                str(n),
                "--batch-size",
                str(n // 4),
                "--timesteps",
                "1000000000",
                "--checkpoint-every",
                str(n * 48 * 10),
                "--max-minutes",
                f"{train_s / 60:.3f}",
            ]
            ppo_code = call(cmd, log, timeout=deadline - time.time() - 10)
            metrics = (
                [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
                if (run / "metrics.jsonl").is_file()
                else []
            )
            sps = [m["training/sps"] for m in metrics if "training/sps" in m]
            summary["ppo"] = {
                "returncode": ppo_code,
                "num_envs": n,
                "training_sps": sps,
                "first_eval_wall_s": next((m["wall_s"] for m in metrics if "eval/episode_reward" in m), None),
            }
            code = code or ppo_code
        summary["returncode"] = code

    summary["wall_s"] = round(time.time() - T0, 1)
    summary["jax"] = jax_info()
    summary["forbidden_imported"] = forbidden_in_log(log)
    (results / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    ok = summary.get("returncode") == 0 and not summary["forbidden_imported"]
    print(
        json.dumps(
            {
                k: summary.get(k)
                for k in ("job", "run", "returncode", "global_step", "num_timesteps", "complete", "wall_s", "tarball")
            }
        )
    )
    return 0 if ok else 1


def link_builds(kit: Path) -> None:
    """build/<feet> -> KIT/build/<feet> where the repository has no build of its own (the envs'
    default build folders, so that the saved policies carry no machine's paths)."""
    for feet in FEET:
        own, theirs = REPO / "build" / feet, kit / "build" / feet
        if (own / "scene.xml").is_file() or not (theirs / "scene.xml").is_file():
            continue
        if own.is_symlink():
            own.unlink()  # a link of an earlier job
        elif own.is_dir() and not any(own.iterdir()):
            own.rmdir()
        elif own.exists():  # something of the user's: never removed
            print(f"run: note: {own} is not a build and not empty; left alone, the kit's build not linked", flush=True)
            continue
        own.parent.mkdir(exist_ok=True)
        try:
            own.symlink_to(theirs, target_is_directory=True)
        except FileExistsError:  # a job started beside this one (campaign.sh) linked it first
            if not (own.is_symlink() and own.resolve() == theirs.resolve()):
                raise


def call(cmd: list[str], log: Path, timeout: float, stdout=None) -> int:
    """Runs cmd, its output appended to log (and echoed), with the interpreter's import trace of
    forbidden modules checked afterwards (forbidden_in_log)."""
    env = dict(os.environ, FOOTFORGE_KIT_TRACE="1")
    print("run:", " ".join(cmd), flush=True)
    with open(log, "a") as f:
        f.write("$ " + " ".join(cmd) + "\n")
        f.flush()
        wrapped = [cmd[0], str(Path(__file__).with_name("trace_imports.py"))] + cmd[1:]
        try:
            proc = subprocess.run(
                wrapped,
                stdout=stdout or subprocess.PIPE,
                stderr=subprocess.STDOUT if stdout is None else f,
                text=True,
                env=env,
                timeout=max(timeout, 1),
            )
        except subprocess.TimeoutExpired:
            f.write("run: killed at the job's time limit\n")
            return 124
        if stdout is None:
            f.write(proc.stdout)
            print(proc.stdout[-4000:], end="")
    return proc.returncode


def forbidden_in_log(log: Path) -> list[str]:
    found = set()
    if log.is_file():
        for line in log.read_text(errors="replace").splitlines():
            if line.startswith("footforge-kit: imported "):
                found.update(line.split()[2:])
    return sorted(found)


def run_state(run: Path) -> dict:
    state = json.loads((run / "progress.json").read_text()) if (run / "progress.json").is_file() else {}
    config = json.loads((run / "config.json").read_text()) if (run / "config.json").is_file() else {}
    total = state.get("num_timesteps") or config.get("ppo", {}).get("num_timesteps")
    step = state.get("global_step", 0)
    return {
        "global_step": step,
        "num_timesteps": total,
        "complete": bool(total) and step >= total,
        "stopped": state.get("stopped"),
        "metrics": state.get("metrics", {}),
    }


def pack(run: Path, results: Path) -> str:
    """results/RUN.tar.gz: the run folder with its newest intact checkpoint only (the manifest
    check of footforge.rl.train; others, and those set aside as *.corrupt, are left out); TensorBoard
    left out when the whole would pass 16 MiB (metrics.jsonl holds the same curves)."""
    from footforge.rl.train import checkpoint_problem, checkpoints as run_checkpoints

    found = [path for _, path in run_checkpoints(run)]
    intact = [p for p in found if checkpoint_problem(p, read=False) is None]
    if found and not intact:
        print(
            f"run: warning: no intact checkpoint in {run.name}; packing the newest, {found[-1].name}", file=sys.stderr
        )
    keep = (intact or found)[-1:]
    folder = run / "checkpoints"
    old = {str(p) for p in folder.iterdir() if p not in keep} if folder.is_dir() else set()
    target = results / f"{run.name}.tar.gz"
    for skip_tb in (False, True):

        def keep(info: tarfile.TarInfo, skip_tb=skip_tb):  # this pass's skip_tb, bound
            path = str(run.parent / info.name)
            if any(path == o or path.startswith(o + "/") for o in old):
                return None
            if skip_tb and (path == str(run / "tensorboard") or path.startswith(str(run / "tensorboard") + "/")):
                return None
            return info

        with tarfile.open(target, "w:gz") as tar:
            tar.add(run, arcname=run.name, filter=keep)
        if target.stat().st_size <= MAX_TARBALL:
            return target.name
    target.unlink()
    raise SystemExit(f"run: error: {run.name}.tar.gz is over 16 MiB even without TensorBoard")


def unpack(source: Path, runs: Path) -> None:
    if source.is_dir():
        dest = runs / source.name
        if dest.resolve() != source.resolve():
            shutil.rmtree(dest, ignore_errors=True)
            shutil.copytree(source, dest, symlinks=True)
        return
    if not source.is_file():
        raise UsageError(f"--resume {source}: no such tarball or folder")
    with tarfile.open(source) as tar:
        names = {n.split("/")[0] for n in tar.getnames()}
        if len(names) != 1 or any(n.startswith("/") or ".." in n.split("/") for n in tar.getnames()):
            raise UsageError(f"--resume {source}: not a RUN.tar.gz of this kit (one run folder)")
        shutil.rmtree(runs / names.pop(), ignore_errors=True)
        tar.extractall(runs, filter="data")


def jax_info() -> dict:
    try:
        out = subprocess.run(
            [
                sys.executable,
                "-c",
                "import jax, json; print(json.dumps({'version': jax.__version__, "
                "'devices': [str(d) for d in jax.devices()]}))",
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        return json.loads(out.stdout.strip().splitlines()[-1])
    except Exception as e:  # reporting only
        return {"error": str(e)}


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
