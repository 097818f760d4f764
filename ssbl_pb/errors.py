"""The one error type for problems with the user's input, and the exit codes the tools use.

Everything a user can get wrong (a flag, a file, a config field, a run directory, a robot address) raises a
``UserError`` (or a subclass) whose message names the value and what was expected. Tools catch only it, in
``ssbl_pb.cli.run``: one line on stderr, exit 2. Anything else is a bug and shows its traceback (exit 1).
"""

from __future__ import annotations

EXIT_USAGE = 2  # bad input: one line naming the problem, nothing left behind
EXIT_SIGINT = 130  # Ctrl-C (128 + SIGINT), the shell's convention
EXIT_SIGTERM = 143  # SIGTERM (128 + 15)


class UserError(ValueError):
    """A problem with the user's input; the message names the file/flag/field and what was expected.

    A ``ValueError`` subclass so that callers that already catch ``ValueError`` keep working; tools must catch
    ``UserError`` only, so that a numpy ``ValueError`` (a bug) is not reported as bad input.
    """


class Terminated(KeyboardInterrupt):
    """Raised in the main thread on SIGTERM (see ``cli.run``), so code that cleans up on Ctrl-C does so too."""
