"""The default builds, build/<feet>/, made on first use by the commands that need them."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from footforge.envs.anymal import DEFAULT_BUILD_ROOT
from footforge.variants import Variant


def build_defaults_if_missing(variants: Iterable[Variant], build_root: Path | None, console=None) -> None:
    """Without a build root given (`build_root` None), builds each of `variants` into
    build/<variant>/ that holds no scene.xml yet, as `footforge build --variant <variant> --format
    mjcf` would. A build root the user gives must hold its builds already: the environments say
    how to make one. An existing build folder is never rebuilt here (the environments refuse a
    stale one with the command that rebuilds it)."""
    if build_root is not None:
        return
    for variant in dict.fromkeys(variants):
        folder = DEFAULT_BUILD_ROOT / variant
        if (folder / "scene.xml").is_file():
            continue
        # Only now: the build's packages (footforge's build extra) are not on the offline GPU
        # machine, which trains from builds made beforehand (scripts/device), nor in a core install.
        from footforge.extras import require_build_extra

        require_build_extra(
            f"{folder} holds no model, and building it",
            alternative="give --build-root with models built by footforge build elsewhere",
        )
        from footforge.build import BuildOptions, build

        message = f"building {variant} into {folder} (footforge build --variant {variant} --format mjcf)"
        if console is None:
            print(message, flush=True)
            build(BuildOptions(variant=variant, out_dir=folder, formats=("mjcf",)))
            continue
        with console.status(message) as status:
            build(
                BuildOptions(variant=variant, out_dir=folder, formats=("mjcf",)),
                progress=lambda stage: status.update(f"{message}: {stage}"),  # noqa: B023  (called in this iteration)
            )
