"""The `footforge` command line: one command for every job, a thin layer over the library.

Each job is a module of footforge/cli/ with the same two functions, parser(prog) and run(args)
(footforge.cli.command: the protocol, the list of commands and the one error path); this module
lists them, parses `footforge [--verbose] [--version] COMMAND`, and runs the command's module on
the rest. pipelines/*.py run the same modules.

Exit codes: 0 success, 1 check failures, 2 usage or input errors. Errors print as messages
that name the file, the element and the fix; `--verbose` adds the traceback.
"""

from __future__ import annotations

import argparse
import sys

import footforge

footforge.headless_by_default()  # before any import of MuJoCo

from footforge.cli.command import COMMANDS, module, run_command  # noqa: E402  (after headless_by_default)
from footforge.errors import EXIT_INPUT_ERROR  # noqa: E402


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's usage errors exit 2, as ours do
        self.print_usage(sys.stderr)
        self.exit(EXIT_INPUT_ERROR, f"footforge: error: {message}\n")


def _versions() -> str:
    """footforge's version and the simulators it was run with (what a bug report needs)."""
    from importlib.metadata import PackageNotFoundError, version

    import footforge

    parts = [footforge.__version__]
    for dist in ("mujoco", "mujoco-mjx", "jax", "brax"):
        try:
            parts.append(f"{dist} {version(dist)}")
        except PackageNotFoundError:
            parts.append(f"{dist} absent")
    return parts[0] + " (" + ", ".join(parts[1:]) + ")"


def _parser() -> argparse.ArgumentParser:
    """`footforge [--verbose] [--version] COMMAND ...`: the list of commands; each parses its own options."""
    from footforge.cli.help import DefaultsHelpFormatter

    p = _Parser(prog="footforge", description=__doc__.splitlines()[0], formatter_class=DefaultsHelpFormatter)
    p.add_argument("--verbose", action="store_true", help="print tracebacks on errors")
    p.add_argument("--version", action="version", version=f"footforge {_versions()}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for name, (_, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    return p


def parsers() -> dict[str, argparse.ArgumentParser]:
    """Every job's argument parser by its command words ("build", ..., "train flat", "train rough"):
    what the help of each shows."""
    from footforge.envs import TASKS

    found: dict[str, argparse.ArgumentParser] = {}
    for name in COMMANDS:
        if name == "train":
            found |= {f"train {task}": module(name).parser(f"footforge train {task}", task) for task in TASKS}
        else:
            found[name] = module(name).parser(f"footforge {name}")
    return found


def _prog(argv: list[str]) -> str:
    """`footforge JOB` (with train's task) as the command's errors name it, or `footforge`."""
    words = [a for a in argv if not a.startswith("-")][:2]
    if not words or words[0] not in COMMANDS:
        return "footforge"
    return (
        f"footforge {words[0]} {words[1]}"
        if words[0] == "train" and words[1:] in (["flat"], ["rough"])
        else f"footforge {words[0]}"
    )


def main(argv: list[str] | None = None) -> int:
    """`footforge ...`: the exit code of the command run."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if footforge.gl_setting_refused(_prog(argv)):  # before `import mujoco` raises on it
        return EXIT_INPUT_ERROR
    first = next((i for i, a in enumerate(argv) if not a.startswith("-")), None)
    if first is None or argv[first] not in COMMANDS or not all(a == "--verbose" for a in argv[:first]):
        try:  # --help, --version, no command, an unknown one: argparse says which (exit 0 or 2)
            _parser().parse_args(argv)
        except SystemExit as e:
            return int(e.code or 0)
        return EXIT_INPUT_ERROR  # not reached: a known command word is handled below
    name, rest, verbose = argv[first], argv[first + 1 :], "--verbose" in argv[:first]
    if name == "train":
        from footforge.cli.train import main_with_task

        return main_with_task(rest, verbose=verbose)
    return run_command(module(name), rest, f"footforge {name}", verbose=verbose)


if __name__ == "__main__":
    sys.exit(main())
