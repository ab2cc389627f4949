"""How footforge's commands end: exit codes and one line on stderr, never a traceback."""

from __future__ import annotations

import sys
from collections.abc import Callable

from footforge.errors import FootforgeError, interrupt_exit_code, interrupt_word
from footforge.processes import sigterm_as_interrupt


def run_guarded(prog: str, work: Callable[[], int], *, interrupted: str = "no output was written") -> int:
    """`work()` as the body of command `prog`, with SIGTERM handled as Ctrl-C (a terminated run
    cleans up as an interrupted one). A FootforgeError prints "prog: error: ..." and returns its exit
    code (1: a check failed; 2: usage or input); an interrupt prints "prog: interrupted; ..."
    ("terminated" for SIGTERM) and returns 130 (Ctrl-C) or 143 (SIGTERM), as shells report them."""
    try:
        with sigterm_as_interrupt():
            return work()
    except FootforgeError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt as e:
        print(f"{prog}: {interrupt_word(e)}; {interrupted}", file=sys.stderr)
        return interrupt_exit_code(e)


def policy_in_use(given, command: str):
    """The folder a command given policy `given` uses (footforge.rl.policy_files.policy_folder: a
    run's policy/, or its newest intact checkpoint), said on stderr when it is not what the user
    named."""
    from footforge.rl.policy_files import folder_note, policy_folder

    used = policy_folder(given)
    note = folder_note(given, used)
    if note:
        print(f"{command}: note: {note}", file=sys.stderr)
    return used
