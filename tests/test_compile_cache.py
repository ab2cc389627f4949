"""JAX's persistent compilation cache (footforge/rl/compile_cache.py): where it lives, how it is
turned off, and that a second process loads what the first compiled."""

import os
import subprocess
import sys
from pathlib import Path

from footforge.rl import compile_cache

# A process that turns the cache on as the pipelines do, compiles one program (JAX's 1 s minimum
# lowered to 0 so that a small program is kept) and prints how many compilations the cache served.
PROGRAM = """
import jax, jax.numpy as jp
hits = []
jax.monitoring.register_event_listener(lambda name, **kw: hits.append(name) if name.endswith("cache_hits") else None)
from footforge.rl import compile_cache
print(compile_cache.enable({enabled}))
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
jax.jit(lambda x: jp.sin(x) @ x.T + 3.0)(jp.ones((5, 5))).block_until_ready()
print(len(hits))
"""


def _run(env: dict, enabled: bool = True) -> list[str]:
    env = {
        k: v for k, v in os.environ.items() if k not in ("FOOTFORGE_COMPILE_CACHE", "JAX_COMPILATION_CACHE_DIR")
    } | env
    done = subprocess.run(
        [sys.executable, "-c", PROGRAM.format(enabled=enabled)], capture_output=True, text=True, env=env, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.split()


def test_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.delenv("FOOTFORGE_COMPILE_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert compile_cache.default_folder() == tmp_path / "xdg" / "footforge" / "jax"
    monkeypatch.setenv("FOOTFORGE_COMPILE_CACHE", str(tmp_path / "mine"))
    assert compile_cache.default_folder() == tmp_path / "mine"
    monkeypatch.setenv("FOOTFORGE_COMPILE_CACHE", "off")
    assert compile_cache.default_folder() is None


def test_a_second_process_loads_what_the_first_compiled(tmp_path):
    folder = tmp_path / "cache"
    first = _run({"FOOTFORGE_COMPILE_CACHE": str(folder)})
    assert first == [str(folder), "0"]
    assert any(p.name.endswith("-cache") for p in folder.iterdir())  # JAX's entries
    second = _run({"FOOTFORGE_COMPILE_CACHE": str(folder)})
    assert second[0] == str(folder) and int(second[1]) >= 1


def test_off_by_flag_or_variable_writes_nothing(tmp_path):
    folder = tmp_path / "cache"
    assert _run({"FOOTFORGE_COMPILE_CACHE": str(folder)}, enabled=False) == ["None", "0"]
    assert _run({"FOOTFORGE_COMPILE_CACHE": "off", "XDG_CACHE_HOME": str(tmp_path / "xdg")}) == ["None", "0"]
    assert not folder.exists() and not (tmp_path / "xdg").exists()


def test_on_the_cpu_the_cache_is_off_unless_a_folder_is_named(tmp_path):
    """JAX 0.9.2's CPU loader logs errors for every program and crashed reloading a long program
    (compile_cache's docstring): on the CPU only FOOTFORGE_COMPILE_CACHE turns it on, and then a
    note says once what XLA's lines mean."""
    assert _run({"XDG_CACHE_HOME": str(tmp_path / "xdg")}) == ["None", "0"]
    assert not (tmp_path / "xdg").exists()
    env = {k: v for k, v in os.environ.items() if k not in ("FOOTFORGE_COMPILE_CACHE", "JAX_COMPILATION_CACHE_DIR")}
    done = subprocess.run(
        [sys.executable, "-c", "from footforge.rl import compile_cache as c; c.enable(); c.enable()"],
        capture_output=True,
        text=True,
        env=env | {"FOOTFORGE_COMPILE_CACHE": str(tmp_path / "c")},
        timeout=300,
    )
    assert done.returncode == 0 and done.stderr.count("note: JAX's compilation cache is on for the CPU") == 1


def test_a_folder_given_to_jax_is_kept(tmp_path):
    """The GPU kit's run.sh sets JAX_COMPILATION_CACHE_DIR: that folder wins."""
    kit = tmp_path / "kit"
    out = _run({"JAX_COMPILATION_CACHE_DIR": str(kit), "FOOTFORGE_COMPILE_CACHE": str(tmp_path / "other")})
    assert out[0] == str(kit) and not (tmp_path / "other").exists()
    assert Path(kit).is_dir()
