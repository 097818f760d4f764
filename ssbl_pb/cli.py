"""Small helpers shared by the command-line tools: error exit and progress bars."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator

EXIT_USAGE = 2


def fail(exc: BaseException | str) -> int:
    """Print a one-line error to stderr; returns the usage exit code (2)."""
    print(f"error: {exc}", file=sys.stderr)
    return EXIT_USAGE


@contextlib.contextmanager
def progress_bar(total: int, desc: str) -> Iterator[Callable[[int], None]]:
    """A tqdm bar as a callable ``advance(n)`` (silent when stderr is not a terminal and CI is set)."""
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit="ep", dynamic_ncols=True, mininterval=0.5)
    try:
        yield bar.update
    finally:
        bar.close()
