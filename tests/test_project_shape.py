"""What a newcomer reads stays short and current: the docs' lengths, no issue numbers, each default written once."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LIMITS = {"README.md": 150, "docs/decisions.md": 300, "docs/benchmarks.md": 450}
ISSUE = re.compile(r"\bissues? ?#?\d+\b", re.IGNORECASE)


@pytest.mark.parametrize("name", sorted(LIMITS))
def test_the_docs_stay_within_their_length(name):
    lines = (ROOT / name).read_text().count("\n")
    assert lines <= LIMITS[name], f"{name}: {lines} lines, at most {LIMITS[name]}"


def test_no_issue_numbers_in_code_tests_or_docs():
    dirs = ("ssbl_pb", "tests", "tools", "docs", "configs")
    files = [ROOT / "README.md", *(p for d in dirs for p in (ROOT / d).rglob("*"))]
    hits = [f"{p.relative_to(ROOT)}:{i}" for p in files if p.is_file() and p.suffix in (".py", ".md", ".yaml")
            for i, line in enumerate(p.read_text(errors="replace").splitlines(), 1) if ISSUE.search(line)]
    assert not hits, hits
    assert ISSUE.search("see issue" + " 14") and not ISSUE.search("tissue 3")  # the pattern finds what it should


def test_the_base_speed_limit_is_written_once():
    from ssbl_pb.core.shield import ShieldParams
    from ssbl_pb.deploy.__main__ import _parser
    from ssbl_pb.deploy.loop import DeployParams
    from ssbl_pb.params import RobotParams

    written = [f"{p.relative_to(ROOT)}" for p in (ROOT / "ssbl_pb").rglob("*.py")
               if re.search(r"max_speed\b[^=\n]*=\s*0\.35\b", p.read_text())]
    assert written == ["ssbl_pb/params.py"], written
    limit = RobotParams().max_speed
    assert DeployParams().max_speed == ShieldParams().max_speed == limit
    assert _parser().parse_args(["--robot-ip", "1.2.3.4"]).max_speed == limit
