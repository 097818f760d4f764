"""Bad input to the tracking tools: one clear error naming the file, exit code 2, no output files."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.perception.datasets.pets import GroundTruthError, load_cvml, load_ground_truth, load_mot
from ssbl_pb.perception.tracking.pipeline import VideoError, open_video

ROOT = Path(__file__).resolve().parents[1]
CALIB = """<?xml version="1.0"?>
<Camera name="c"><Geometry width="768" height="576" dpx="0.005" dpy="0.005"/>
<Intrinsic focal="5.5" kappa1="0.005" cx="324" cy="282" sx="1.09"/>
<Extrinsic tx="828" ty="-3175" tz="35469" rx="2.04" ry="-0.89" rz="-0.43"/></Camera>
"""
CVML = """<?xml version="1.0"?><dataset><frame number="0"><objectlist>
<object id="3"><box h="80" w="30" xc="100" yc="200"/></object></objectlist></frame></dataset>
"""


def run_tool(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], cwd=ROOT, capture_output=True, text=True, timeout=120)


def test_cvml_and_mot_loaders(tmp_path):
    p = tmp_path / "gt.xml"
    p.write_text(CVML)
    rows = load_cvml(p)
    assert rows.tolist() == [[0, 3, 85.0, 160.0, 30.0, 80.0, 1.0]]
    m = tmp_path / "gt.txt"
    m.write_text("1,3,85,160,30,80,1,-1,-1,-1\n")
    assert np.allclose(load_mot(m), rows)
    assert np.allclose(load_ground_truth(m), rows)


@pytest.mark.parametrize("name,text,match", [
    ("gt.xml", "<annotations><track id='1'/></annotations>", r"gt\.xml.*CVML XML"),
    ("gt.xml", "frame,id\n1,2\n", r"gt\.xml: not valid XML.*CVML"),
    ("gt.json", "{}", r"gt\.json: unknown ground-truth format '.json'"),
    ("gt.xml", CVML.replace(' xc="100"', ""), r"gt\.xml: frame '0'.*CVML"),
    ("gt.txt", "1,2,3\n", r"gt\.txt: 3 columns; expected MOTChallenge"),
])
def test_gt_in_another_format(tmp_path, name, text, match):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(GroundTruthError, match=match):
        load_ground_truth(p)


def test_video_errors(tmp_path):
    with pytest.raises(VideoError, match="not found"):
        open_video(tmp_path / "none.avi")
    bad = tmp_path / "bad.avi"
    bad.write_bytes(b"\x00" * 100)
    with pytest.raises(VideoError, match=r"bad\.avi: cannot be opened"):
        open_video(bad)


def test_track_cli_bad_video_and_calibration(tmp_path):
    bad = tmp_path / "bad.avi"
    bad.write_text("not a video")
    calib = tmp_path / "cam.xml"
    calib.write_text(CALIB)
    out = tmp_path / "out"
    r = run_tool("tools/track.py", str(bad), "--calib", str(calib), "--out", str(out))
    assert r.returncode == 2 and "bad.avi" in r.stderr and "cannot be opened" in r.stderr
    assert not out.exists() and [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    # a real (tiny) video but a calibration lacking a field
    vid = tmp_path / "tiny.avi"
    w = cv2_writer(vid)
    for _ in range(3):
        w.write(np.zeros((576, 768, 3), np.uint8))
    w.release()
    calib.write_text(CALIB.replace(' kappa1="0.005"', ""))
    r = run_tool("tools/track.py", str(vid), "--calib", str(calib), "--out", str(out))
    assert r.returncode == 2 and "cam.xml" in r.stderr and "kappa1" in r.stderr
    assert not out.exists()


def cv2_writer(path):
    import cv2
    return cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (768, 576))


def test_eval_cli_bad_gt(tmp_path):
    tracks = tmp_path / "trk"
    tracks.mkdir()
    (tracks / "tracks_mot.txt").write_text("1,1,10,10,20,40,1,-1,-1,-1\n")
    gt = tmp_path / "gt.csv"
    gt.write_text("frame,id\n")
    r = run_tool("tools/eval_tracking.py", "--tracks", str(tracks), "--gt", str(gt))
    assert r.returncode == 2 and "gt.csv" in r.stderr and "expected" in r.stderr
    assert sorted(p.name for p in tracks.iterdir()) == ["tracks_mot.txt"]


def test_tools_help():
    for tool in ("tools/track.py", "tools/eval_tracking.py", "tools/bench_tracking.py"):
        r = run_tool(tool, "--help")
        assert r.returncode == 0 and "usage" in r.stdout
