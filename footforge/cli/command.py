"""How every footforge command starts and ends: one protocol, one error path.

A command is a module of footforge/cli/ with two functions,

    parser(prog) -> argparse.ArgumentParser   its options and help (train's: parser(prog, task))
    run(args) -> int                          its work; 0, or 1 where a check or validation failed

and, where an interrupted run leaves something worth naming, `interrupted(args) -> str | None`: what it
left behind ("no output was written" without one), or None where Ctrl-C is the normal way out (the
viewer of `footforge play`, exit 0). Bad input raises footforge.errors.FootforgeError inside run(),
before long work: InputError is exit 2, CheckFailure exit 1.

`run_command` is the only place that turns these into exit codes and one line on stderr,
`footforge <command>: error: <what, where, the fix>`, whichever way the command was started
(`footforge <command>`, `python -m footforge.cli`, or a pipelines/*.py shim), and that handles
SIGTERM as Ctrl-C, so that a batch scheduler's kill cleans up as an interrupted run does.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback
from pathlib import Path
from types import ModuleType

COMMANDS: dict[str, tuple[str, str]] = {
    "build": ("build", "build MJCF models of ANYmal C with a foot variant"),
    "validate": ("validate", "drop tests of AFF/AOF/ball against the closed chain; fidelity report"),
    "check": ("check", "report physical and structural defects of a URDF or xacro"),
    "train": ("train", "train a policy: footforge train flat|rough [options] (Brax PPO on MuJoCo)"),
    "evaluate": (
        "evaluate",
        "the paper's indices and the walking verdict of trained policies, on any feet; policy card, plots, GIF",
    ),
    "evaluate-closed-chain": (
        "evaluate_closed_chain",
        "run trained policies on the 34-joint closed-chain feet (CPU MuJoCo)",
    ),
    "play": ("play", "watch a trained policy walk: MuJoCo's viewer with keyboard commands, or headless with a GIF"),
    "export": ("export", "write a trained policy as ONNX (normaliser inside, metadata for deployment)"),
}
"""Each command's module under footforge/cli/ and its line in `footforge --help`."""

NOTHING_WRITTEN = "no output was written"
"""What an interrupted command says it left where its module has no interrupted(args)."""


def module(command: str) -> ModuleType:
    """The module of `command` (a key of COMMANDS), imported on use: a command's start pays for its own imports."""
    return importlib.import_module(f"footforge.cli.{COMMANDS[command][0]}")


def run_command(
    command: ModuleType, argv: list[str] | None, prog: str, *, name: str | None = None, verbose: bool = False, **options
) -> int:
    """Runs `command` (a module with parser() and run()) on `argv` (sys.argv[1:] when None). `prog`
    is how it was started, in its usage line (`python pipelines/play.py`); `name`, the command's words
    in its messages (`footforge play`; default `prog`), the same whichever way it was started;
    `options` go to its parser(). Returns the exit code:
    run()'s, argparse's (0 for --help, 2 for a usage error), a FootforgeError's, or 130/143 for
    Ctrl-C/SIGTERM. `verbose` adds the traceback to an error's line."""
    import footforge

    footforge.headless_by_default()  # before any import of MuJoCo
    from footforge.errors import EXIT_INPUT_ERROR, EXIT_OK, FootforgeError, interrupt_exit_code, interrupt_word
    from footforge.processes import sigterm_as_interrupt

    name = name or prog
    if footforge.gl_setting_refused(name):  # before `import mujoco` raises on it
        return EXIT_INPUT_ERROR
    try:
        args = command.parser(prog, **options).parse_args(sys.argv[1:] if argv is None else argv)
    except SystemExit as e:  # argparse's --help (0) and usage errors (2), as exit codes
        return int(e.code or 0)
    try:
        with sigterm_as_interrupt():
            return command.run(args)
    except FootforgeError as e:
        if verbose:
            traceback.print_exc()
        print(f"{name}: error: {e}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt as e:
        left = command.interrupted(args) if hasattr(command, "interrupted") else NOTHING_WRITTEN
        if left is None:
            return EXIT_OK
        print(f"{name}: {interrupt_word(e)}; {left}", file=sys.stderr)
        return interrupt_exit_code(e)


def add_output_folder(p: argparse.ArgumentParser, default: Path | None, what: str) -> None:
    """--out and --force of a command that writes a folder: replaced only where footforge wrote it
    (footforge.outputs), so that a user's files are never lost without --force."""
    p.add_argument(
        "--out",
        type=Path,
        default=default,
        help=f"{what}; replaced only if footforge wrote it (or it is empty), see --force",
    )
    p.add_argument(
        "--force", action="store_true", help="replace --out even if footforge did not write it (it may hold your files)"
    )


def new_parser(prog: str, description: str | None, *, docstring: bool = False) -> argparse.ArgumentParser:
    """A command's parser: help that shows every default (footforge.cli.help), the description as
    written where `docstring` (a module docstring with its usage examples)."""
    from footforge.cli.help import DefaultsHelpFormatter, DocstringHelpFormatter

    return argparse.ArgumentParser(
        prog=prog,
        description=description,
        formatter_class=DocstringHelpFormatter if docstring else DefaultsHelpFormatter,
    )
