"""JAX's persistent compilation cache for footforge's commands: a second run of the same
configuration (a resumed training, another evaluation of a policy, a benchmark repeated) loads the
compiled programs instead of compiling them again (minutes on a CPU for the MJX environments).

On a GPU it is on by default in the training and evaluation commands and the benchmarks, in a
user cache folder: `$XDG_CACHE_HOME/footforge/jax` (default `~/.cache/footforge/jax`).
`--no-compile-cache` (or FOOTFORGE_COMPILE_CACHE=off) turns it off. A folder already given to JAX
(JAX_COMPILATION_CACHE_DIR, as the GPU kit's run.sh sets) is kept. JAX keys each entry by the
program, the compile options, the JAX and XLA versions and the device, so an entry is never used
for another machine's or version's program.

On the CPU it is off unless FOOTFORGE_COMPILE_CACHE names a folder (as the test suite and CI do).
JAX 0.9.2's XLA:CPU loader logs two error lines per loaded program ("Loading XLA:CPU AOT result
... could lead to execution errors such as SIGILL": it takes the LLVM tuning flags
prefer-no-gather/scatter for CPU features, jax-ml/jax#38445), and it crashed: on this project's
2-core machine, reloading one 400-operation jitted chain from the cache ended in a segmentation
fault in two of two tries, where compiling it took 7 s (2026-11-27). footforge's own programs
have loaded without a crash in every CI run, but a user's second run must not risk one: on the
CPU the cache is the user's choice. Where it is chosen, enable() says once what those lines are.
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


CPU_NOTE = (
    "note: JAX's compilation cache is on for the CPU ({folder}); XLA may log 'Loading XLA:CPU AOT "
    "result ... could lead to execution errors such as SIGILL' for each program it loads: tuning flags it "
    "cannot match (jax-ml/jax#38445). FOOTFORGE_COMPILE_CACHE=off turns the cache off"
)
"""Said once where the CPU cache is chosen (FOOTFORGE_COMPILE_CACHE set)."""


def enable(enabled: bool = True) -> Path | None:
    """Turns the cache on (before the first compilation) and returns its folder, or None where it
    stays off: asked off, FOOTFORGE_COMPILE_CACHE=off, or on the CPU without FOOTFORGE_COMPILE_CACHE
    naming a folder (the module's docstring says why). Entries are kept when their compilation took
    at least 1 s (JAX's default)."""
    import jax

    if not enabled:
        return None
    # jax.config's options are attributes made at run time (no type information).
    if jax.config.jax_compilation_cache_dir:  # type: ignore[attr-defined]  # set by JAX_COMPILATION_CACHE_DIR (the GPU kit) or the caller
        return Path(jax.config.jax_compilation_cache_dir)  # type: ignore[attr-defined]
    folder = default_folder()
    if folder is None:
        return None
    if jax.default_backend() == "cpu":
        if "FOOTFORGE_COMPILE_CACHE" not in os.environ:
            return None
        _note_once(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:  # an unwritable home: compile as before rather than fail
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    return folder


_noted = False


def _note_once(folder: Path) -> None:
    import sys

    global _noted
    if not _noted:
        print(CPU_NOTE.format(folder=folder), file=sys.stderr, flush=True)
    _noted = True
