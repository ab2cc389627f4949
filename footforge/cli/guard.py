"""What the commands that take a trained policy say about the folder they use."""

from __future__ import annotations

import sys


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
