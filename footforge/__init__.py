"""footforge: simulation models, validation and training for robots with passive adaptive feet."""

import ctypes as _ctypes
import os as _os
import sys as _sys

# MuJoCo loads the OpenGL backend named by MUJOCO_GL when it is imported, and with
# MUJOCO_GL=osmesa (or egl) on a machine without that library `import mujoco` itself fails deep in
# PyOpenGL ("'NoneType' object has no attribute 'glGetError'"). So the library is looked for the
# way PyOpenGL does (dlopen of libNAME.so, then libNAME.so.N); where it is missing, MuJoCo is
# imported without rendering and footforge.rl.render refuses with the reason and the fix.
GL_SET_BY_FOOTFORGE = False
"""Whether MUJOCO_GL=disable was footforge's choice (headless_by_default: the user named no backend)."""
GL_UNAVAILABLE: "tuple[str, str] | None" = None
"""(backend asked for in MUJOCO_GL, why it cannot load), or None when nothing was switched off."""


GL_SETTINGS = (
    "glfw",
    "egl",
    "osmesa",
    "",
    "on",
    "enable",
    "enabled",
    "true",
    "1",
    "off",
    "disable",
    "disabled",
    "false",
    "0",
)
"""MUJOCO_GL values that both MuJoCo and dm_control accept on Linux, as written: dm_control compares
the value as it is (dm_control/_render/constants.py), MuJoCo lower-cased (mujoco/rendering/classic/
gl_context.py: also glx; egl and osmesa on Linux only; wgl, cgl on Windows and macOS)."""


def gl_setting_error() -> "str | None":
    """For footforge's command lines, first thing: why MUJOCO_GL's value would make `import mujoco` or
    `import dm_control` raise (an input error: exit 2), or None when it is unset or accepted."""
    value = _os.environ.get("MUJOCO_GL")
    if value is None or value in GL_SETTINGS or "mujoco" in _sys.modules:
        return None
    return (
        f"MUJOCO_GL={value!r} is not a value MuJoCo and dm_control accept ({', '.join(repr(v) for v in GL_SETTINGS)}): "
        "set egl, osmesa or glfw to render, disable not to, or unset it"
    )


def gl_setting_refused(prog: str) -> bool:
    """For each command line's main, first thing: print `prog: error: ...` and return True where
    MUJOCO_GL's value would make `import mujoco` raise (gl_setting_error; the command exits 2)."""
    error = gl_setting_error()
    if error is not None:
        print(f"{prog}: error: {error}", file=_sys.stderr)
    return error is not None


def _missing_gl_library(backend: str) -> "str | None":
    name = {"osmesa": "OSMesa", "egl": "EGL"}.get(backend)
    if name is None:
        return None
    base = f"lib{name}.so"
    for filename in [base] + [f"{base}.{major}" for major in range(9, -1, -1)]:
        try:
            _ctypes.CDLL(filename)
            return None
        except OSError:
            continue
    return f"lib{name} was not found by the dynamic loader"


def _check_gl_backend() -> None:
    global GL_UNAVAILABLE
    if "mujoco" in _sys.modules or "MUJOCO_GL" not in _os.environ:  # settled, or MuJoCo's own default
        return
    if gl_setting_error() is not None:  # `import mujoco` raises naming it: the command lines refuse it first
        return
    backend = _os.environ["MUJOCO_GL"].lower()
    reason = _missing_gl_library(backend)
    if reason is not None:  # `import mujoco` would fail: import it without rendering instead
        GL_UNAVAILABLE = (backend, reason)
        _os.environ["MUJOCO_GL"] = "disable"


def headless_by_default() -> None:
    """For footforge's command lines, before anything imports MuJoCo: MUJOCO_GL=disable where it
    is unset. footforge authors models with dm_control.mjcf and renders only where asked (and
    then says which backend to set); without a backend named, dm_control probes for an X display
    (GLFW) at import and warns on headless machines. Importing footforge as a library leaves
    MUJOCO_GL as the user's script has it."""
    global GL_SET_BY_FOOTFORGE
    if "MUJOCO_GL" not in _os.environ and "mujoco" not in _sys.modules:
        _os.environ["MUJOCO_GL"] = "disable"
        GL_SET_BY_FOOTFORGE = True
    _check_gl_backend()
    _hold_back_warp_lines()


WARP_ABSENT = ("Failed to import warp:", "Failed to import mujoco_warp:")
"""The starts of the two lines `import mujoco.mjx` prints on stdout where warp-lang is missing."""


class _QuietMjxWarp:
    """An import hook for the module mujoco.mjx.warp, which every import of MJX (footforge's, or
    Brax's, which imports MJX whatever one imports from it) runs once. Where warp-lang is missing it
    prints "Failed to import warp: ..." and "Failed to import mujoco_warp: ..." on stdout at every
    start. footforge's default MJX backend is "jax", which needs neither, and
    EnvConfig.mjx_impl="warp" says itself what is missing (envs.anymal.check_mjx_impl): these two
    lines are held back, and anything else the module prints passes through."""

    NAME = "mujoco.mjx.warp"

    def find_spec(self, fullname, path=None, target=None):
        if fullname != self.NAME:
            return None
        import importlib.machinery

        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is not None and spec.loader is not None:
            spec.loader = _QuietLoader(spec.loader)  # type: ignore[assignment]  # the loader, wrapped
        return spec


class _QuietLoader:
    """The module's own loader, its exec_module run with stdout filtered; every other attribute
    (is_package, get_source, get_resource_reader, ...) is the wrapped loader's."""

    def __init__(self, loader):
        self.loader = loader

    def __getattr__(self, name):
        return getattr(self.loader, name)

    def create_module(self, spec):
        return self.loader.create_module(spec)

    def exec_module(self, module):
        import contextlib
        import io

        printed = io.StringIO()
        try:
            with contextlib.redirect_stdout(printed):
                self.loader.exec_module(module)
        finally:
            for line in printed.getvalue().splitlines(keepends=True):
                if not line.startswith(WARP_ABSENT):
                    _sys.stdout.write(line)


def _hold_back_warp_lines() -> None:
    """For footforge's command lines (headless_by_default): installs _QuietMjxWarp once."""
    if not any(isinstance(finder, _QuietMjxWarp) for finder in _sys.meta_path):
        _sys.meta_path.insert(0, _QuietMjxWarp())


_check_gl_backend()

__version__ = "0.1.0"

# The library's entry points, imported on first use so that `import footforge` stays light (no
# MuJoCo, no JAX). The packages themselves (footforge.build, .validate, .envs, .rl) are imported
# by name as usual; these are the classes and functions a script starts from.
_EXPORTS = {
    "BuildOptions": "footforge.build.pipeline",
    "check_description": "footforge.build.check",
    "ValidateOptions": "footforge.validate.runner",
    "make_env": "footforge.envs",
    "load_policy": "footforge.rl.policy_files",
}
__all__ = ["__version__", "headless_by_default", *_EXPORTS]


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'footforge' has no attribute '{name}'")
    import importlib

    module = importlib.import_module(_EXPORTS[name])
    return getattr(module, "make" if name == "make_env" else name)
