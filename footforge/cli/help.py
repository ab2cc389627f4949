"""How footforge's commands present themselves: --help with every default shown (in the help's
own words where it already says it), and tables that fit where they are printed."""

from __future__ import annotations

import argparse
import os


class DefaultsHelpFormatter(argparse.HelpFormatter):
    """argparse's help with "(default: X)" added to each option whose help does not name its default
    already. Options without a value (flags), and those defaulting to None, show nothing: None means
    "not given", and the help says what happens then."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (
            action.option_strings
            and "default" not in text.lower()
            and "%(default)" not in text
            and default is not None
            and default is not argparse.SUPPRESS
            and not isinstance(default, bool)
            and default != []
        ):
            text += " (default: %(default)s)"
        return text


class DocstringHelpFormatter(DefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """DefaultsHelpFormatter with the description printed as written: a module docstring with its
    usage examples."""


PIPED_WIDTH = 200
"""Columns of the tables printed into a file or a pipe, where rich would otherwise cut them to 80."""


def console(stderr: bool = False):
    """A rich console: the terminal's width on a terminal; PIPED_WIDTH columns when the output is
    piped or logged (unless COLUMNS says otherwise), so that tables are not cut."""
    from rich.console import Console

    out = Console(stderr=stderr)
    if not out.is_terminal and "COLUMNS" not in os.environ:
        out = Console(stderr=stderr, width=PIPED_WIDTH)
    return out


def counted_progress(console):
    """A rich progress display of counted work (a bar, done of total, time elapsed) that vanishes
    when the work ends, leaving the command's own summary."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
    )
