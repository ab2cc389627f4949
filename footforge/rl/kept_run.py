"""What git keeps of a training run (policies/README.md): a run copied into a policy folder with its weights
once and its learning curve gzipped, so that the folder can be evaluated, played and resumed. The thin CLI is
scripts/keep_run.py."""

from __future__ import annotations

import gzip
import json
import os
import shutil
import tempfile
from pathlib import Path

from footforge.atomic import atomic_file, remove_stale_temporaries, remove_stale_temporaries_in
from footforge.errors import InputError
from footforge.outputs import MARKER
from footforge.rl.checkpoints import checkpoints, latest_intact_checkpoint
from footforge.rl.policy_files import policy_problem
from footforge.rl.run_folder import CURVE, CURVE_KEPT, is_run_folder


def keep_run(run_dir: Path, dest: Path) -> list[str]:
    """Copies into `dest` what git keeps of the run in `run_dir` (policies/README.md): config.json,
    progress.json, the marker, the learning curve gzipped (CURVE_KEPT: a sixth of its bytes; a
    resume unpacks it), and the run's weights once. A run that reached its total keeps policy/ (and
    dest's checkpoints/ go); a run still in training keeps its newest intact checkpoint under
    checkpoints/ (the older checkpoints in dest go). dest's other files (evaluation/, closed_chain/)
    stay. Each entry is written beside its place and renamed in, so a kill leaves dest as it was or
    with whole entries. Returns what it wrote.

    Raises:
      InputError: run_dir is not a training run, has no intact checkpoint, or dest holds files that
        are not a run's.
    """
    run_dir, dest = Path(run_dir).resolve(), Path(dest).resolve()
    if not is_run_folder(run_dir) or not (run_dir / "progress.json").is_file():
        raise InputError(
            "not a training run (no config.json or progress.json)", file=str(run_dir), fix="give a run's --out"
        )
    if dest == run_dir:
        raise InputError("the run and where to keep it are the same folder", file=str(dest), fix="give another folder")
    if dest.exists() and any(dest.iterdir()) and not is_run_folder(dest):
        raise InputError(
            "holds files that are not a footforge run's, which keeping a run there could mix with its own",
            file=str(dest),
            fix="give a new folder or the folder this run was kept in before",
        )
    saved = json.loads((run_dir / "config.json").read_text())
    step = int(json.loads((run_dir / "progress.json").read_text()).get("global_step", 0))
    finished = step >= int(saved["ppo"]["num_timesteps"])
    if finished:
        problem = "missing" if not (run_dir / "policy").is_dir() else policy_problem(run_dir)
        if problem:
            raise InputError(
                f"reached its total steps but its policy/ is not the final one ({problem})",
                file=str(run_dir / "policy"),
                fix=f"footforge train {saved['env'].get('task', 'flat')} --out {run_dir} --resume writes it",
            )
    newest = None if finished else latest_intact_checkpoint(run_dir)
    if not finished and newest is None:
        raise InputError(
            "has no intact checkpoint to keep", file=str(run_dir / "checkpoints"), fix="resume the run first"
        )
    dest.mkdir(parents=True, exist_ok=True)
    written = []
    for name in ("config.json", "progress.json", MARKER):
        if (run_dir / name).is_file():
            with atomic_file(dest / name) as tmp:
                shutil.copyfile(run_dir / name, tmp)
            written.append(name)
    if (run_dir / CURVE).is_file():
        with atomic_file(dest / CURVE_KEPT) as tmp:
            tmp.write_bytes(gzip.compress((run_dir / CURVE).read_bytes(), mtime=0))  # mtime 0: the same bytes each time
        (dest / CURVE).unlink(missing_ok=True)  # the gzipped copy replaces it (prepare_run_dir refuses both)
        written.append(CURVE_KEPT)
    if finished:
        _replace_tree(run_dir / "policy", dest / "policy")
        shutil.rmtree(dest / "checkpoints", ignore_errors=True)
        written.append("policy")
    else:
        assert newest is not None
        target = dest / "checkpoints" / newest[1].name
        target.parent.mkdir(exist_ok=True)
        _replace_tree(newest[1], target)
        for _, older in checkpoints(dest):
            if older != target:
                shutil.rmtree(older)
        # A killed call's copy of an older checkpoint, which checkpoints() does not list (a hidden name).
        remove_stale_temporaries_in(target.parent)
        written.append(f"checkpoints/{newest[1].name}")
    return written


def _replace_tree(source: Path, target: Path) -> None:
    """Copies the folder `source` to `target`, replacing it whole: a copy beside it, renamed in, with
    footforge.atomic's names for the copy and the folder set aside, so that a later call removes what a
    killed one left (remove_stale_temporaries). Not atomic_directory itself: that writes footforge's
    marker into the new folder, and the copy is to be the run's folder byte for byte (a checkpoint holds
    what orbax wrote and the manifest listing it, a policy/ what policy_files wrote)."""
    remove_stale_temporaries(target)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-{os.getpid()}-", dir=target.parent))
    try:
        shutil.copytree(source, tmp, dirs_exist_ok=True)
        if target.exists():
            old = target.with_name(f".{target.name}.old-{os.getpid()}")
            os.replace(target, old)
            os.replace(tmp, target)
            shutil.rmtree(old)
        else:
            os.replace(tmp, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
