"""Worker processes that do not outlive their parent, and SIGTERM handled like Ctrl-C.

A killed `footforge validate` used to leave its pool workers (about 195 MB each) blocked forever on
their pipes, and a killed build its CoACD process running: nothing tells a child that its parent
died. `die_with_parent` is called first thing in each worker. A polite kill (SIGTERM) used to end
the process at once, skipping the clean-up that Ctrl-C runs (removing half-written output folders,
stopping workers); `sigterm_as_interrupt` turns it into that same KeyboardInterrupt.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

PR_SET_PDEATHSIG = 1
"""prctl option (linux/prctl.h): the signal this process gets when its parent dies."""
WATCH_INTERVAL_S = 0.5


def _exit_if_orphaned(parent_pid: int) -> None:
    while True:
        if os.getppid() != parent_pid:
            os._exit(1)
        time.sleep(WATCH_INTERVAL_S)


def die_with_parent(parent_pid: int) -> None:
    """Makes this (child) process exit when the process `parent_pid` that started it dies.

    Two mechanisms, since each covers a gap of the other:
    - Linux's prctl(PR_SET_PDEATHSIG, SIGKILL) kills even a child stuck in C code that holds the
      GIL (CoACD). The kernel sends it when the parent *thread* that started the child ends, so
      start workers from a thread that lives as long as they are needed (footforge does).
    - a daemon thread that polls os.getppid() (it changes when the parent dies) works on every
      POSIX system, for children that run Python or wait on a pipe.
    If the parent is already gone when this runs, the process exits at once.
    """
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass  # no prctl (another libc): the watchdog thread below still works
    if os.getppid() != parent_pid:
        os._exit(1)
    threading.Thread(target=_exit_if_orphaned, args=(parent_pid,), daemon=True, name="footforge-parent-watch").start()


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised as an interrupt (sigterm_as_interrupt): cleaned up as Ctrl-C is, but it exits
    143, not 130 (footforge.errors.interrupt_exit_code)."""


def _raise_interrupt(signum, frame):
    raise Terminated(f"signal {signum}")


@contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM raises Terminated (a KeyboardInterrupt) in the main thread, so a
    terminated run cleans up exactly as an interrupted one does. Restores the previous handler after; does
    nothing outside the main thread (where Python cannot install handlers)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
