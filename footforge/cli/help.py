"""How footforge's commands print --help: every default shown, in the help's own words where it
already says it."""

from __future__ import annotations

import argparse


class DefaultsHelpFormatter(argparse.HelpFormatter):
    """argparse's help with "(default: X)" added to each option whose help does not name its default
    already. Options without a value (flags), and those defaulting to None, show nothing: None means
    "not given", and the help says what happens then."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (action.option_strings and "default" not in text.lower() and "%(default)" not in text
                and default is not None and default is not argparse.SUPPRESS and not isinstance(default, bool)
                and default != []):
            text += " (default: %(default)s)"
        return text


class DocstringHelpFormatter(DefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """DefaultsHelpFormatter with the description printed as written: a module docstring with its
    usage examples."""
