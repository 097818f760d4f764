"""Perceptual-study analysis on constructed data with a hand-computed t."""

import math
import subprocess
import sys
from pathlib import Path

import pytest

from ssbl_pb.analysis.study import StudyError, analyze

ROOT = Path(__file__).resolve().parents[1]


def write(path: Path, rows: list[str]) -> Path:
    path.write_text("participant,condition,item,rating,video\n" + "\n".join(rows) + "\n")
    return path


def test_paired_t_by_hand(tmp_path):
    # polite: A - B differences per participant = 1, 2, 0, 1 (video ratings averaged first for P1)
    rows = ["P1,A,polite,5,v1", "P1,A,polite,7,v2", "P1,B,polite,5,v1",
            "P2,A,polite,6,v1", "P2,B,polite,4,v1",
            "P3,A,polite,3,v1", "P3,B,polite,3,v1",
            "P4,A,polite,4,v1", "P4,B,polite,3,v1"]
    res = analyze(write(tmp_path / "r.csv", rows))
    t = res["items"]["polite"]["test"]
    sd = math.sqrt(2 / 3)  # differences 1, 2, 0, 1: mean 1, sample sd sqrt(2/3)
    assert t["df"] == 3
    assert t["t"] == pytest.approx(1 / (sd / 2))
    assert t["d_z"] == pytest.approx(1 / sd)
    assert res["items"]["polite"]["A"]["mean"] == pytest.approx((6 + 6 + 3 + 4) / 4)


def test_example_file_runs(tmp_path):
    res = subprocess.run([sys.executable, str(ROOT / "tools" / "analyze_study.py"),
                          str(ROOT / "docs" / "examples" / "ratings_example.csv"), "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    assert "t(19)" in res.stdout
    assert (tmp_path / "study.png").stat().st_size > 1000


@pytest.mark.parametrize("rows,message", [
    (["P1,A,polite,9,v"], "outside the 1-7"),
    (["P1,A,polite,x,v"], "not an integer"),
    (["P1,A,kind,3,v"], "item 'kind'"),
])
def test_bad_rows_named(tmp_path, rows, message):
    with pytest.raises(StudyError, match=message):
        analyze(write(tmp_path / "r.csv", rows))


def test_missing_column(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("participant,cond,item,rating\nP1,A,polite,3\n")
    with pytest.raises(StudyError, match="missing column"):
        analyze(p)
