"""Output folders that appear whole or not at all.

The output is written into a temporary folder beside it, `.NAME.tmp-PID-XXXX`, and renamed into
place at the end; a folder being replaced is first renamed aside to `.NAME.old-PID`. The PID in
both names lets a later run tell the leftovers of a killed run (whose process is gone, so nothing
else removed them) from those of a run still going: `remove_stale_temporaries`.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from footforge.errors import InputError
from footforge.outputs import check_output_folder, write_marker, written_by_footforge


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


# `.NAME.tmp-PID-SUFFIX` (SUFFIX: mkdtemp's) or `.NAME.old-PID`: the names atomic_directory gives
# its temporary folder and the folder it sets aside.
_LEFTOVER = re.compile(r"^\.(?P<name>.+)\.(?:tmp-(?P<tmp_pid>\d+)-[a-z0-9_]+|old-(?P<old_pid>\d+))$")


def _remove_stale(parent: Path, name: str | None) -> list[Path]:
    """Removes the leftovers in `parent` of killed runs: of the output `name`, or of any output (None)."""
    if not parent.is_dir():
        return []
    removed = []
    for entry in sorted(parent.iterdir()):
        m = _LEFTOVER.match(entry.name)
        if not m or (name is not None and m["name"] != name) or entry.is_symlink() or not entry.is_dir():
            continue
        pid = int(m["tmp_pid"] or m["old_pid"])
        if pid != os.getpid() and not _process_alive(pid):
            shutil.rmtree(entry, ignore_errors=True)
            removed.append(entry)
    return removed


def remove_stale_temporaries(out_dir: Path) -> list[Path]:
    """Removes the temporary and set-aside folders of `out_dir` left by runs that were killed.

    Only names of the form `.NAME.tmp-PID-...` and `.NAME.old-PID` whose process no longer exists
    on this machine (a PID reused by another process keeps the leftover until it ends). Returns
    the removed paths.
    """
    out_dir = Path(out_dir)
    return _remove_stale(out_dir.parent, out_dir.name)


def remove_stale_temporaries_in(folder: Path) -> list[Path]:
    """remove_stale_temporaries for every output in `folder` at once: the leftovers of outputs that
    no longer exist too (a killed copy of a checkpoint since superseded), which no later write of
    the same name would find."""
    return _remove_stale(Path(folder), None)


@contextmanager
def atomic_directory(out_dir: Path, *, force: bool = False, command: str | None = None) -> Iterator[Path]:
    """Yields a temporary folder beside `out_dir`; on success it replaces `out_dir` by rename, on
    any error (or interruption) it is deleted and `out_dir` is left as it was.

    `out_dir` may be new, empty, or a folder footforge wrote (it holds outputs.MARKER); any other
    folder only with `force` (outputs.check_output_folder, checked on entry and again before the
    replacement, since the folder may have changed meanwhile). The new folder gets the marker,
    naming `command` (default: this process's command line).

    A symbolic link `out_dir` stays: the folder it points to is the one checked and written or
    replaced (check_output_folder; renaming the link aside would leave it behind, since a link is
    never deleted here, and put a plain folder where the user had a link).

    Raises:
      InputError: `out_dir` may not be written or replaced.
    """
    out_dir = check_output_folder(Path(out_dir), force=force)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(out_dir)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.tmp-{os.getpid()}-", dir=out_dir.parent))
    umask = os.umask(0)
    os.umask(umask)
    tmp.chmod(0o777 & ~umask)  # mkdtemp makes 0700; the output is an ordinary folder
    try:
        yield tmp
        write_marker(tmp, command)
        if out_dir.is_dir() and (force or written_by_footforge(out_dir) or not any(out_dir.iterdir())):
            old = out_dir.with_name(f".{out_dir.name}.old-{os.getpid()}")
            os.replace(out_dir, old)
            os.replace(tmp, out_dir)
            shutil.rmtree(old, ignore_errors=True)
        elif out_dir.exists() or out_dir.is_symlink():
            check_output_folder(out_dir, force=force)  # raises: someone put files there meanwhile
            raise InputError(f"{out_dir}: appeared during the run; not replaced")
        else:
            os.replace(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


@contextmanager
def atomic_file(path: Path) -> Iterator[Path]:
    """Yields a temporary path beside `path` (same suffix, so writers can tell the format); on
    success it replaces `path`, on any error it is deleted."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_json(path: Path, data: dict) -> None:
    """Writes `data` as JSON to `path` whole or not at all (a temporary `.NAME.tmp` renamed into
    place): a run killed mid-write must still resume."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    os.replace(tmp, path)
