"""JAX's persistent compilation cache for footforge's commands: a second run of the same
configuration (a resumed training, another evaluation of a policy, a benchmark repeated) loads the
compiled programs instead of compiling them again (minutes on a CPU for the MJX environments).

On by default in the training and evaluation pipelines and the benchmarks, in a user cache folder:
`$FOOTFORGE_COMPILE_CACHE` if set, else `$XDG_CACHE_HOME/footforge/jax` (default
`~/.cache/footforge/jax`). `--no-compile-cache` (or FOOTFORGE_COMPILE_CACHE=off) turns it off. A
folder already given to JAX (JAX_COMPILATION_CACHE_DIR, as the GPU kit's run.sh sets) is kept.
JAX keys each entry by the program, the compile options, the JAX and XLA versions and the device,
so an entry is never used for another machine's or version's program.
"""

from __future__ import annotations

import os
from pathlib import Path

OFF = ("off", "0", "no", "false")


def default_folder() -> Path | None:
    """The cache folder for this user (None: turned off by FOOTFORGE_COMPILE_CACHE=off)."""
    chosen = os.environ.get("FOOTFORGE_COMPILE_CACHE")
    if chosen is not None:
        return None if chosen.strip().lower() in OFF else Path(chosen).expanduser()
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "footforge" / "jax"


def enable(enabled: bool = True) -> Path | None:
    """Turns the cache on (before the first compilation) and returns its folder, or None where it
    stays off. Entries are kept when their compilation took at least 1 s (JAX's default)."""
    import jax

    if not enabled:
        return None
    if jax.config.jax_compilation_cache_dir:  # set by JAX_COMPILATION_CACHE_DIR (the GPU kit) or the caller
        return Path(jax.config.jax_compilation_cache_dir)
    folder = default_folder()
    if folder is None:
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:  # an unwritable home: compile as before rather than fail
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    return folder
