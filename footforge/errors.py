"""Error types and the exit-code convention of the command line.

Exit codes: 0 success, 1 validation or check failures, 2 usage or input errors, and as shells
report a process ended by a signal (128 + its number): 130 interrupted (Ctrl-C, SIGINT), 143
terminated (SIGTERM, a batch scheduler's kill). An interrupted or terminated command first cleans up
what it was writing and says what was kept.
Every error names the file, the element and the fix, so the CLI prints it without a traceback.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_INPUT_ERROR = 2
EXIT_INTERRUPTED = 130
"""128 + SIGINT (2)."""
EXIT_TERMINATED = 143
"""128 + SIGTERM (15)."""


def interrupt_exit_code(interrupt: BaseException) -> int:
    """The exit code of a command stopped by `interrupt` (a KeyboardInterrupt): 143 where it came
    from SIGTERM (footforge.processes.sigterm_as_interrupt raises Terminated), else 130."""
    from footforge.processes import Terminated

    return EXIT_TERMINATED if isinstance(interrupt, Terminated) else EXIT_INTERRUPTED


def interrupt_word(interrupt: BaseException) -> str:
    """How a command's last line names its stop: 'terminated' (SIGTERM) or 'interrupted'."""
    return "terminated" if interrupt_exit_code(interrupt) == EXIT_TERMINATED else "interrupted"


class FootforgeError(Exception):
    """Base class of the errors that the CLI reports as a message, not a traceback."""

    exit_code = EXIT_INPUT_ERROR

    def __init__(self, message: str, *, file: str | None = None, element: str | None = None, fix: str | None = None):
        super().__init__(message)
        self.message = message
        self.file = file
        self.element = element
        self.fix = fix

    def __str__(self) -> str:
        parts = []
        if self.file:
            parts.append(str(self.file))
        if self.element:
            parts.append(self.element)
        where = ": ".join(parts)
        text = f"{where}: {self.message}" if where else self.message
        if self.fix:
            text += f"\n  fix: {self.fix}"
        return text


class InputError(FootforgeError):
    """Bad user input: a missing file, a malformed description, an unknown option value."""

    exit_code = EXIT_INPUT_ERROR


class CheckFailure(FootforgeError):
    """A description or model failed a physical or structural check."""

    exit_code = EXIT_CHECK_FAILED
