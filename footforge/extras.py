"""The optional dependencies a command needs (pyproject.toml's extras), checked before it starts.

`pip install footforge` trains, evaluates, exports and plays policies on models built beforehand.
Building and checking models (`footforge build`, `validate`, `check`, and the first-use builds of
build/<feet> by `train`, `evaluate`, `evaluate-closed-chain` and `play`) needs the `build` extra:
a command without it stops with exit 2 and the install command, not an ImportError's traceback.
"""

from __future__ import annotations

import importlib.util

from footforge.errors import InputError

BUILD_EXTRA = {
    "dm_control": "dm-control",
    "xacro": "xacro",
    "pxr": "usd-core",
    "trimesh": "trimesh",
    "coacd": "coacd",
    "fast_simplification": "fast-simplification",
    "pinocchio": "pin",
    "lxml": "lxml",
    "yaml": "PyYAML",
    "scipy": "scipy",
}
"""The `build` extra's distributions (pyproject.toml, tests/test_packaging.py keeps them equal), by
the module each one provides. Some come with the core set anyway (trimesh and scipy with
mujoco-mjx, PyYAML with flax); they are listed because footforge's building imports them."""

BUILD_INSTALL = 'pip install "footforge[build]" (in a clone: pip install -c constraints.txt -e ".[build]")'
"""How to add the build extra, as the refusals say it."""


def missing_build_packages() -> list[str]:
    """The build extra's distributions whose module cannot be found here (none: it is installed).
    Found, not imported: the check is cheap and imports no OpenGL or USD library."""
    return [dist for module, dist in BUILD_EXTRA.items() if importlib.util.find_spec(module) is None]


def require_build_extra(what: str, alternative: str | None = None) -> None:
    """Returns where the build extra is installed.

    Raises:
      InputError: (exit 2) a distribution of the build extra is missing: "`what` needs footforge's
        build extra", the missing ones, and the install command (or `alternative`) as the fix.
    """
    missing = missing_build_packages()
    if missing:
        raise InputError(
            f"{what} needs footforge's build extra (the model-building packages), which is not "
            f"installed: {', '.join(missing)} missing",
            fix=BUILD_INSTALL + (f", or {alternative}" if alternative else ""),
        )
