"""Timing of a long command's stages, with a progress message as each one starts."""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import contextmanager


class StageTimer:
    """Timings and a progress callback per stage."""

    def __init__(self, progress: Callable[[str], None] | None):
        self.progress = progress or (lambda msg: None)
        self.timings_s: dict[str, float] = {}

    @contextmanager
    def __call__(self, name: str):
        self.progress(name)
        t0 = time.perf_counter()
        yield
        self.timings_s[name] = round(time.perf_counter() - t0, 4)
