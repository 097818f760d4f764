"""Where numba keeps the compiled code: a cache folder named by a hash of the sources of every package with some.

numba's own cache (``cache=True``) checks only the source file of the function it compiled: ``kernels.step``
compiled before an edit of ``reward.py`` or ``obstacles.py`` that it calls would keep running the old terms (it
did, once, while the range scan was being changed). Keying the folder on every module of the packages with compiled
code, ``ssbl_pb.core`` and ``ssbl_pb.env`` (``COMPILED``), makes any edit recompile everything once (~1 min)
instead. A ``NUMBA_CACHE_DIR`` set by the user is left alone.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
import time
from pathlib import Path

_SET_BY_US = "_SSBL_PB_NUMBA_CACHE"
COMPILED = ("core", "env")  # the packages holding numba-compiled functions
KEEP_OLD_S = 86400.0  # folders of other keys are dropped once unused this long (a run of the old code may live)


def source_key(folder: Path) -> str:
    """A short hash of every ``.py`` file in ``folder`` and its sub-folders (paths and contents)."""
    h = hashlib.sha1()
    for f in sorted(folder.rglob("*.py")):
        h.update(f.relative_to(folder).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def compiled_key() -> str:
    """The key of every package in ``COMPILED`` (their names and ``source_key``s)."""
    package = Path(__file__).resolve().parents[1]
    h = hashlib.sha1()
    for name in COMPILED:
        h.update(name.encode())
        h.update(source_key(package / name).encode())
    return h.hexdigest()[:12]


def use_source_keyed_cache() -> Path | None:
    """Point numba's cache at ``__pycache__/numba-KEY`` beside these sources (or ``~/.cache/ssbl_pb`` where that
    is read-only), dropping the folders of other keys untouched for a day; returns the folder (None if the user
    chose one)."""
    if "NUMBA_CACHE_DIR" in os.environ and os.environ.get(_SET_BY_US) != os.environ["NUMBA_CACHE_DIR"]:
        return None
    here = Path(__file__).resolve().parent
    name = f"numba-{compiled_key()}"
    for root in (here / "__pycache__", Path.home() / ".cache" / "ssbl_pb"):
        try:
            (root / name).mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(root / name, os.W_OK):
            break
    else:
        return None
    for old in root.glob("numba-*"):
        if old.name != name and time.time() - old.stat().st_mtime > KEEP_OLD_S:
            shutil.rmtree(old, ignore_errors=True)
    os.environ["NUMBA_CACHE_DIR"] = os.environ[_SET_BY_US] = str(root / name)
    if "numba" in sys.modules:  # imported before us: make it read the folder again
        from numba.core import config

        config.reload_config()
    return root / name
