"""Checkpoints that survive a kill: `<run>/checkpoints/<global step>/`.

Brax's own checkpoints hold the policy, value and normaliser parameters but restart the step count
on resume; footforge names each checkpoint by the run's global step (save_checkpoint, called
after every epoch of training).

Integrity: every checkpoint gets `footforge_checkpoint.json` (CHECKPOINT_MANIFEST), written whole
after Brax's and orbax's files are complete, with each file's size and SHA-256. A resume verifies
checkpoints from the newest down and continues from the newest intact one (resume_point); the
ones it skips (no manifest, a file truncated, missing or changed, or unreadable by orbax) are
named and renamed to `<step>.corrupt` so the resumed run can write that step again. A checkpoint
without a manifest is one whose write did not finish (a kill between orbax's files and the
manifest: orbax may well read it, but not every file need be complete), except in runs from before
the manifest, where no checkpoint has one: those are accepted when orbax reads them
(`legacy_run`).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

from footforge.atomic import write_json
from footforge.errors import InputError
from footforge.rl.config import PPOConfig
from footforge.rl.networks import network_factory

CHECKPOINT_MANIFEST = "footforge_checkpoint.json"
"""In every checkpoint folder (and the policy folder copied from one): {"files": {relative path:
{"bytes", "sha256"}}}, written whole once the checkpoint's files are complete."""


def checkpoints(run_dir: Path) -> list[tuple[int, Path]]:
    """(global step, folder) of the run's checkpoints, oldest first (intact or not)."""
    folder = Path(run_dir) / "checkpoints"
    found = sorted((int(p.name), p) for p in folder.iterdir() if p.name.isdigit()) if folder.is_dir() else []
    return found


def _resumable(run_dir: Path) -> list[tuple[int, Path]]:
    """The run's checkpoints, or, where it has none, its policy/ as the checkpoint of its step: a
    shipped policy's folder keeps its weights once (policy/ is a copy of the newest checkpoint's
    files, plus footforge.json), and resumes from them."""
    found = checkpoints(run_dir)
    if found:
        return found
    policy = Path(run_dir) / "policy"
    try:
        step = int(json.loads((policy / "footforge.json").read_text())["global_step"])
    except (OSError, ValueError, KeyError, TypeError):
        return []
    return [(step, policy)] if (policy / CHECKPOINT_MANIFEST).is_file() else []


def latest_checkpoint(run_dir: Path) -> tuple[int, Path] | None:
    """The newest checkpoint, intact or not (latest_intact_checkpoint checks)."""
    found = checkpoints(run_dir)
    return found[-1] if found else None


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_checkpoint_manifest(folder: Path) -> None:
    """Records every file under the checkpoint folder `folder` (size and SHA-256) in its manifest."""
    folder = Path(folder)
    files = {
        str(p.relative_to(folder)): {"bytes": p.stat().st_size, "sha256": _sha256(p)}
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != CHECKPOINT_MANIFEST
    }
    write_json(folder / CHECKPOINT_MANIFEST, {"files": files})


def legacy_run(run_dir: Path) -> bool:
    """Whether the run's checkpoints are from before manifests: it has some, and none has one."""
    found = checkpoints(run_dir)
    return bool(found) and not any((path / CHECKPOINT_MANIFEST).is_file() for _, path in found)


def checkpoint_problem(folder: Path, *, read: bool = True, legacy: bool = False) -> str | None:
    """Why the checkpoint folder `folder` cannot be trusted, or None if it is intact.

    With a manifest, every file it lists must be there with its size and SHA-256. Without one, the
    write did not finish, except with `legacy` (a run from before manifests, legacy_run): then
    Brax's network config must be there and, as with `read`, orbax must read the parameters.
    """
    folder = Path(folder)
    manifest = folder / CHECKPOINT_MANIFEST
    if manifest.is_file():
        try:
            files = json.loads(manifest.read_text())["files"]
        except (OSError, ValueError, KeyError, TypeError):
            return f"its {CHECKPOINT_MANIFEST} is unreadable"
        for name, expected in files.items():
            path = folder / name
            if not path.is_file():
                return f"{name} is missing"
            if path.stat().st_size != expected["bytes"]:
                return f"{name} has {path.stat().st_size} bytes, {expected['bytes']} were written"
            if _sha256(path) != expected["sha256"]:
                return f"{name} changed since it was written (SHA-256 differs)"
    elif not legacy:
        return f"no {CHECKPOINT_MANIFEST}: its write did not finish"
    elif not (folder / "ppo_network_config.json").is_file():
        return f"no {CHECKPOINT_MANIFEST} and no ppo_network_config.json: its write did not finish"
    else:
        read = True
    if read:
        try:
            load_parameters(folder)
        except Exception as e:  # orbax raises many types on damaged files; the reason is reported
            first = (str(e).strip().splitlines() or [""])[0]
            return f"orbax cannot read it ({type(e).__name__}: {first[:160]})"
    return None


def load_parameters(folder: Path):
    from brax.training.agents.ppo import checkpoint as brax_checkpoint

    return brax_checkpoint.load(os.path.abspath(folder))  # orbax refuses a relative path


def latest_intact_checkpoint(run_dir: Path, *, read: bool = False) -> tuple[int, Path] | None:
    """The newest checkpoint that passes checkpoint_problem (without checkpoints/, policy/: _resumable)."""
    legacy = legacy_run(run_dir)
    for step, path in reversed(_resumable(run_dir)):
        if checkpoint_problem(path, read=read, legacy=legacy) is None:
            return step, path
    return None


def resume_point(run_dir: Path, notice: Callable[[str], None], set_aside: bool):
    """(global step, parameters) of the newest intact checkpoint; the newer ones are reported and,
    with `set_aside`, renamed to <step>.corrupt (the resumed run writes those steps again).

    Raises:
      InputError: no checkpoint, or none intact.
    """
    found = _resumable(run_dir)
    if not found:
        raise InputError(
            f"nothing to resume: no checkpoints in {run_dir / 'checkpoints'} and no policy/",
            file=str(run_dir),
            fix="start without --resume (with --force to start this run over), or give another run",
        )
    skipped: list[tuple[int, Path]] = []
    legacy = legacy_run(run_dir)
    for step, path in reversed(found):
        problem = checkpoint_problem(path, read=False, legacy=legacy)
        params = None
        if problem is None:
            try:
                params = load_parameters(path)
            except Exception as e:  # as in checkpoint_problem
                problem = f"orbax cannot read it ({type(e).__name__})"
        if problem is None:
            for _, bad in skipped:
                if set_aside:
                    aside = bad.with_name(f"{bad.name}.corrupt")
                    n = 1
                    while aside.exists():
                        aside, n = bad.with_name(f"{bad.name}.corrupt{n}"), n + 1
                    os.replace(bad, aside)
            return step, params
        notice(f"skipping checkpoint {path.name} of {run_dir}: {problem}")
        skipped.append((step, path))
    raise InputError(
        f"no intact checkpoint to resume in {run_dir / 'checkpoints'} ({len(found)} checked, "
        f"all damaged; the reasons are above)",
        file=str(run_dir),
        fix="start the run over with --force (it removes the run's files), or give another --out",
    )


def save_checkpoint(
    run_dir: Path,
    global_step: int,
    params,
    observation_size,
    action_size: int,
    ppo: PPOConfig,
    privileged: bool = False,
) -> Path:
    """Writes <run_dir>/checkpoints/<global_step>/ as training does: Brax's checkpoint of
    (normaliser, policy, value) parameters, then its manifest (CHECKPOINT_MANIFEST)."""
    from brax.training.agents.ppo import checkpoint as brax_checkpoint

    brax_checkpoint.save(
        str(Path(run_dir) / "checkpoints"),
        global_step,
        params,
        brax_checkpoint.network_config(
            observation_size, action_size, ppo.normalize_observations, network_factory(ppo, privileged)
        ),
    )
    folder = Path(run_dir) / "checkpoints" / f"{global_step:012d}"
    write_checkpoint_manifest(folder)
    return folder
