"""The compiled code's cache folder follows every source of ssbl_pb.core and ssbl_pb.env, not only the compiled
function's file."""

import os
import subprocess
import sys

from ssbl_pb.core.compile_cache import source_key


def test_an_edit_of_any_module_changes_the_key(tmp_path):
    (tmp_path / "kernels.py").write_text("def step(): return reward()\n")
    (tmp_path / "reward.py").write_text("def reward(): return 1.0\n")
    before = source_key(tmp_path)
    assert source_key(tmp_path) == before
    (tmp_path / "reward.py").write_text("def reward(): return 2.0\n")  # kernels.py untouched
    assert source_key(tmp_path) != before


def test_the_compiled_code_caches_by_key_and_leaves_a_users_folder_alone(tmp_path):
    code = "import os, ssbl_pb.core; print(os.environ['NUMBA_CACHE_DIR'])"
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "_SSBL_PB_NUMBA_CACHE")}
    ours = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert os.path.basename(ours.stdout.strip()).startswith("numba-")
    theirs = subprocess.run([sys.executable, "-c", code], env={**env, "NUMBA_CACHE_DIR": str(tmp_path)},
                            capture_output=True, text=True, check=True)
    assert theirs.stdout.strip() == str(tmp_path)


def test_an_edit_in_a_sub_package_changes_the_key(tmp_path):
    (tmp_path / "engine").mkdir()
    (tmp_path / "engine" / "kernels.py").write_text("def step(): return 1.0\n")
    before = source_key(tmp_path)
    (tmp_path / "engine" / "kernels.py").write_text("def step(): return 2.0\n")
    assert source_key(tmp_path) != before
    (tmp_path / "engine" / "kernels.py").rename(tmp_path / "kernels.py")  # a move changes it too
    assert source_key(tmp_path) != before


def test_every_compiled_module_lies_in_a_keyed_package():
    """numba code outside ``COMPILED`` would keep running stale compiled copies after an edit."""
    from pathlib import Path

    from ssbl_pb.core.compile_cache import COMPILED

    package = Path(__file__).resolve().parents[1] / "ssbl_pb"
    compiled = {f.relative_to(package).parts[0] for f in package.rglob("*.py") if "numba" in f.read_text()
                and "njit" in f.read_text()}
    assert compiled and compiled <= set(COMPILED), compiled
