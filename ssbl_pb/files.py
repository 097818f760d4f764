"""Writing results safely: atomic files with normal permissions, output folders checked before any work.

Every result is written to a temporary file beside its target and renamed over it, so a reader (or a run killed
mid-write) sees the old file or the whole new one, never half of one. ``output_dir`` creates a tool's output
folder only once inputs are checked, and removes what it created if the tool then fails.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import yaml

from .errors import UserError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, writer: Callable[[Path], None]) -> Path:
    """Call ``writer(tmp_path)`` and rename the result to ``path`` (same folder, same suffix, mode 0666 & ~umask)."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError, PermissionError) as exc:
        raise UserError(f"{path}: cannot create its folder ({exc.strerror})") from exc
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        writer(tmp_path)
        os.chmod(tmp_path, 0o666 & ~_umask())  # mkstemp makes 0600 files
        os.replace(tmp_path, path)
    finally:
        tmp_path.unlink(missing_ok=True)
    return path


def atomic_write_all(writers: dict[Path, Callable[[Path], None]]) -> None:
    """``atomic_write`` for files that belong together: every temporary file is written first, then all are
    renamed in one go (a kill between the renames is a few microseconds wide instead of a whole write)."""
    temps: dict[Path, Path] = {}
    try:
        for path, writer in writers.items():
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
            os.close(fd)
            temps[path] = Path(tmp)
            writer(temps[path])
            os.chmod(temps[path], 0o666 & ~_umask())
        for path, tmp in temps.items():
            os.replace(tmp, path)
    finally:
        for tmp in temps.values():
            tmp.unlink(missing_ok=True)


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` atomically."""
    return atomic_write(path, lambda p: p.write_text(text))


def write_json(path: str | Path, data: Any) -> Path:
    """Write JSON atomically (numpy scalars as floats)."""
    return write_text(path, json.dumps(data, indent=2, default=float) + "\n")


def copy_file(src: str | Path, dst: str | Path) -> Path:
    """Copy ``src`` to ``dst`` atomically."""
    return atomic_write(dst, lambda p: shutil.copyfile(src, p))


def make_stage_dir(parent: Path, prefix: str) -> Path:
    """A temporary folder inside ``parent`` with normal permissions (mkdtemp makes 0700)."""
    stage = Path(tempfile.mkdtemp(dir=parent, prefix=prefix))
    os.chmod(stage, 0o777 & ~_umask())
    return stage


def replace_dir(stage: Path, target: Path) -> None:
    """Move the complete folder ``stage`` to ``target`` (same parent), replacing what was there: the old folder is
    renamed aside first and removed last. A kill in between leaves ``.NAME.old-*`` beside no ``target``, which
    ``remove_temporaries`` puts back."""
    old = None
    if target.exists():
        old = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.old-"))
        os.replace(target, old)  # over the empty folder mkdtemp made
    os.replace(stage, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


_TEMP = re.compile(r"^\.(?P<stem>.+)\.[a-z0-9_]{8}(?P<suffix>\.[^.]+)?$")  # atomic_write's mkstemp names


def remove_temporaries(folder: Path, owned: Callable[[str], bool], folders: Iterable[str] = ()) -> list[Path]:
    """Remove what a killed writer left in ``folder``: ``atomic_write``'s temporary files of the names ``owned``
    accepts, and the stages of ``replace_dir`` for each name in ``folders`` (``.NAME.new-*``; ``.NAME.old-*`` is
    put back as NAME when NAME is missing, else removed). Returns what was removed."""
    removed: list[Path] = []
    if not folder.is_dir():
        return removed
    for name in folders:
        for old in sorted(folder.glob(f".{name}.old-*")):
            if old.is_dir() and not (folder / name).exists():
                os.replace(old, folder / name)  # killed between replace_dir's two renames: the old one is whole
            else:
                shutil.rmtree(old, ignore_errors=True)
                removed.append(old)
        for new in folder.glob(f".{name}.new-*"):
            shutil.rmtree(new, ignore_errors=True)
            removed.append(new)
    for p in folder.iterdir():
        m = _TEMP.match(p.name)
        if m and p.is_file() and owned(m["stem"] + (m["suffix"] or "")):
            p.unlink(missing_ok=True)
            removed.append(p)
    return removed


def check_output_path(path: str | Path, flag: str = "--out", is_dir: bool = True) -> Path:
    """Check that ``path`` can be created or written (a folder if ``is_dir``), leaving nothing behind: a
    temporary folder is made and removed where it would go (``os.access`` says yes to root everywhere, even in
    ``/proc``)."""
    path = Path(path)
    if path.exists():
        if is_dir and not path.is_dir():
            raise UserError(f"{flag} {path}: exists and is not a directory")
        if not is_dir and path.is_dir():
            raise UserError(f"{flag} {path}: is a directory, expected a file name")
        target = path if path.is_dir() else path.parent
    else:
        target = path.parent
        while not target.exists():
            target = target.parent
        if not target.is_dir():
            raise UserError(f"{flag} {path}: {target} is a file, not a directory")
    if not os.access(target, os.W_OK | os.X_OK):
        raise UserError(f"{flag} {path}: {target} is not writable")
    try:
        os.rmdir(tempfile.mkdtemp(dir=target, prefix=".ssbl-check-"))
    except OSError as exc:
        raise UserError(f"{flag} {path}: cannot create anything in {target} ({exc.strerror})") from exc
    return path


@contextlib.contextmanager
def output_dir(path: str | Path, flag: str = "--out") -> Iterator[Path]:
    """Create ``path`` (after ``check_output_path``); on an exception remove every folder this call created."""
    path = check_output_path(path, flag)
    created: list[Path] = []
    p = path
    while not p.exists():
        created.append(p)
        p = p.parent
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        for d in created:
            shutil.rmtree(d, ignore_errors=True)
        raise UserError(f"{flag} {path}: cannot create it ({exc.strerror})") from exc
    try:
        yield path
    except BaseException:
        for d in created:  # deepest first
            shutil.rmtree(d, ignore_errors=True)
        raise


class _Dumper(yaml.SafeDumper):
    """Block mappings, flow lists (as ROS camera_info files are written)."""


def _list_flow(dumper: yaml.SafeDumper, data: list) -> yaml.Node:
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=True)


_Dumper.add_representer(list, _list_flow)


def write_yaml(path: str | Path, data: dict[str, Any], header: str = "") -> Path:
    """Write a mapping as block-style YAML (lists inline) atomically, with an optional ``#`` comment header."""
    body = yaml.dump(data, Dumper=_Dumper, sort_keys=False, default_flow_style=False, width=100)
    head = "".join(f"# {line}\n" for line in header.splitlines()) if header else ""
    return write_text(path, head + body)


def source_commit() -> str | None:
    """This checkout's short commit (with ``+`` when tracked files have changes), or None outside git: results
    record the code that made them."""
    root = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, check=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+" if dirty else "")
