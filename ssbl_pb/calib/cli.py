"""Shared command-line plumbing for tools/: bad input exits with code 2 and one clear message."""

from __future__ import annotations

import sys
from collections.abc import Callable

from ..params import ConfigError

EXIT_BAD_INPUT = 2


def run(main: Callable[[list[str] | None], int | None], argv: list[str] | None = None) -> int:
    """Call ``main(argv)``; ``ConfigError``/``ValueError``/``OSError`` print ``error: ...`` and return 2."""
    try:
        return int(main(argv) or 0)
    except (ConfigError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
