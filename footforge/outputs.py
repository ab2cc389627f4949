"""Which output folders footforge may write, and replace.

An output folder is replaced as a whole (footforge.atomic), so a careless `--out` could delete a
user's files. footforge therefore replaces only a folder it wrote itself, recognised by the marker
file MARKER that it writes into every output folder; an empty folder is filled; anything else is
refused unless the user passes `--force`. The checks run before the long work (a build runs
CoACD for minutes), so a bad `--out` fails in a second with one line, not after the work with a
traceback.

`check_output_folder` is the one entry point, meant for every command with an output folder
(build, validate, the evaluation pipelines; training's run folder can call it too).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from footforge.errors import InputError

MARKER = ".footforge-output"
"""File in every output folder footforge writes: a small JSON naming the tool, command and version."""


TRAINING_RUN = "training run"
"""The marker's `kind` in a training run folder: written into over many calls (checkpoints,
--resume), so it is never replaced as a whole unless forced (footforge.rl.run_folder.prepare_run_dir)."""


ACCUMULATING = "accumulating"
"""The marker's `kind` in a folder filled over many calls, each adding to what earlier ones left
(scripts/paper_comparison.py's pairs): never replaced as a whole unless forced, like a training run."""

KEPT_WHOLE = {
    TRAINING_RUN: "a training run folder (checkpoints, metrics)",
    ACCUMULATING: "a folder filled over many calls (such as scripts/paper_comparison.py's pairs)",
}
"""Marker kinds whose folders check_output_folder refuses to replace without force, and what they are."""


def write_marker(folder: Path, command: str | None = None, *, kind: str | None = None) -> None:
    """Writes the marker into `folder` (a folder footforge is writing), so a later run may replace
    it; `kind` (e.g. TRAINING_RUN) is recorded for folders that need more care."""
    from footforge import __version__

    if command is None:
        command = " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])
    (Path(folder) / MARKER).write_text(
        json.dumps(
            {"tool": "footforge", "command": command, "version": __version__} | ({"kind": kind} if kind else {}),
            indent=1,
        )
        + "\n"
    )


def marker_kind(folder: Path) -> str | None:
    """The `kind` the marker of `folder` records, or None (no marker, or none recorded)."""
    try:
        return json.loads((Path(folder) / MARKER).read_text()).get("kind")
    except (OSError, ValueError, AttributeError):
        return None


LEGACY_BUILD_REPORT = "build_report.json"
"""What footforge build wrote into every build folder before the marker existed."""


def written_by_footforge(folder: Path) -> bool:
    """Whether `folder` holds footforge's marker file (content not trusted, only its presence), or
    is a build folder from before the marker: its build_report.json names a footforge version."""
    folder = Path(folder)
    if (folder / MARKER).is_file():
        return True
    try:
        report = json.loads((folder / LEGACY_BUILD_REPORT).read_text())
        return bool(report.get("versions", {}).get("footforge")) and "variant" in report
    except (OSError, ValueError, AttributeError):
        return False


def _nearest_existing(path: Path) -> Path:
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_output_folder(path: Path, *, force: bool = False, flag: str = "--out", force_flag: str = "--force") -> Path:
    """Checks that `path` can be written as an output folder that replaces what is there.

    Call it before any long work. `flag` and `force_flag` name the command's options in the
    message. Returns the absolute path: for a link, the folder it points to, which is what is
    checked and what gets written (the link stays; with `force` a linked user's folder is
    replaced like any other).

    Refused always: the current folder or one above it (it cannot be replaced by a rename), an
    existing file (footforge writes folders; a file is the user's), a path under a file, and a
    parent folder this process cannot write in (the output is made beside it, then renamed).
    Refused unless `force`: an existing non-empty folder without footforge's marker, and a folder
    whose marker's kind is in KEPT_WHOLE (a training run's folder, an accumulating one).

    Raises:
      InputError: one line naming the path and what to change; exit 2.
    """
    given = Path(path)
    target = Path(os.path.abspath(given))
    linked = target.is_symlink()
    if linked and not target.exists():
        raise InputError(f"{flag} {given}: is a broken link; remove it or give another {flag} folder")
    if linked:
        target = target.resolve()
    cwd = Path.cwd()
    if target == cwd or target in cwd.parents:
        raise InputError(
            f"{flag} {given}: {'links to' if linked else 'is'} the current folder or one above it, "
            f"which footforge would replace as a whole; give a new or footforge-written folder, "
            f"e.g. {flag} build/out"
        )
    if target.exists() and not target.is_dir():
        raise InputError(
            f"{flag} {given}: is a file, not a folder; footforge does not replace files: give another {flag} folder"
        )
    parent = _nearest_existing(target.parent)
    if not parent.is_dir():
        raise InputError(
            f"{flag} {given}: {parent} is a file, so no folder can be made under it; give another {flag} folder"
        )
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(
            f"{flag} {given}: cannot write in {parent} (permission denied); give a {flag} folder in a writable place"
        )
    kind = marker_kind(target) if target.is_dir() else None
    if kind in KEPT_WHOLE and not force:
        raise InputError(
            f"{flag} {given}: is {KEPT_WHOLE[kind]}, which footforge "
            f"does not replace as a whole; give another {flag} folder, e.g. {flag} {given}/evaluation"
        )
    if target.is_dir() and not force and not written_by_footforge(target) and any(target.iterdir()):
        raise InputError(
            f"{flag} {given}: the folder holds files footforge did not write (no {MARKER}); "
            f"pass {force_flag} to replace it anyway, or give another {flag} folder"
        )
    return target


def check_output_file(out: Path, flag: str = "--out") -> None:
    """Refuses an output file path that cannot be written (a folder, a missing or non-folder
    parent, no permission); call it before the slow work. The file itself is written whole by
    footforge.atomic.atomic_file. `flag` names the command's option in the fix.

    Raises:
      InputError: naming the path and what to change; exit 2.
    """
    if out.is_dir():
        raise InputError("is a folder", file=str(out), fix="give a file name, e.g. policy.onnx")
    parent = out.parent  # Path("x").parent is Path(".")
    if not parent.is_dir():
        why = "is not a folder" if parent.exists() else "does not exist"
        raise InputError(
            f"its folder {parent} {why}", file=str(out), fix=f"create the folder first or choose another {flag}"
        )
    if not os.access(parent, os.W_OK | os.X_OK) or (out.exists() and not os.access(out, os.W_OK)):
        raise InputError("not writable", file=str(out), fix=f"choose a writable {flag} path")
