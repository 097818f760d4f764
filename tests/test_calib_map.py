"""Map import: map_server conventions, a synthetic room with a door, the real Willow Garage map, bad input."""

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from ssbl_pb.calib.room_map import extract_room, read_map, room_to_map, room_yaml
from ssbl_pb.params import CalibrationError, load_yaml

ROOT = Path(__file__).resolve().parents[1]


def write_map(folder: Path, origin=(-3.0, 2.0, 0.0), negate: int = 0) -> Path:
    """A 0.05 m grid: a 6 x 4 m room (walls 0.1 m) with a 0.8 m door into a corridor, and a table."""
    res = 0.05
    img = np.full((140, 200), 205, np.uint8)  # unknown
    img[10:100, 10:140] = 254  # room interior + walls drawn below
    img[10:100, 10:12] = img[10:100, 138:140] = 0
    img[10:12, 10:140] = img[98:100, 10:140] = 0
    img[100:130, 10:190] = 254  # corridor below the room
    img[98:100, 60:76] = 254  # 0.8 m door
    img[40:50, 90:110] = 0  # a table
    if negate:
        img = 255 - img
    cv2.imwrite(str(folder / "m.pgm"), img)
    yml = folder / "m.yaml"
    yml.write_text(f"image: m.pgm\nresolution: {res}\norigin: {list(origin)}\nnegate: {negate}\n"
                   "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return yml


@pytest.mark.parametrize("negate", [0, 1])
def test_map_conventions(tmp_path, negate):
    m = read_map(write_map(tmp_path, negate=negate))
    assert m.grid.shape == (140, 200)
    assert m.grid[0, 0] == -1 and m.grid[10, 10] == 1 and m.grid[50, 50] == 0
    # bottom-left pixel's corner is the origin; row 0 is the top
    assert m.cell_to_map(np.array([[139, 0]]))[0] == pytest.approx([-3.0 + 0.025, 2.0 + 0.025])
    xy = m.cell_to_map(np.array([[12.0, 34.0]]))
    assert m.map_to_pixel(xy)[0] == pytest.approx([34.0, 12.0])


def test_room_from_seed_stops_at_the_door(tmp_path):
    m = read_map(write_map(tmp_path))
    seed = tuple(m.cell_to_map(np.array([[70, 30]]))[0])
    room = extract_room(m, seed=seed, door_width=0.9)
    # interior cells 12..97 x 12..137: 6.3 x 4.3 m wall to wall
    assert room.room_size == pytest.approx((6.3, 4.3), abs=0.051)
    x0, y0 = m.cell_to_map(np.array([[97.5, 11.5]]))[0]
    assert room.bounds[:2] == pytest.approx((x0, y0), abs=0.051)
    data = room_yaml(m, room, seed)
    # the room frame's origin is the room centre: room (0, 0) -> map centre of the interior
    centre = m.cell_to_map(np.array([[54.5, 74.5]]))[0]
    assert room_to_map(np.zeros(2), data["map_to_room"])[0] == pytest.approx(centre, abs=0.051)
    free = extract_room(m, seed=seed, size_from="free")
    assert free.room_size[0] < 6.3 and free.free_fraction < 1.0  # the table takes space


def test_real_willow_map(shared_data):
    m = read_map(shared_data / "maps" / "willow-full.yaml")
    assert m.grid.shape == (526, 584) and m.resolution == 0.1
    room = extract_room(m, region=(35.0, 12.0, 50.0, 25.0))
    assert room.room_size == pytest.approx((15.0, 12.6), abs=0.11)  # the lab at x 35-50, y 12-25 m
    assert room.centre == pytest.approx((42.5, 18.7), abs=0.11)
    assert 0.6 < room.free_fraction < 0.95


def test_bad_maps_fail_clearly(tmp_path):
    yml = write_map(tmp_path)
    text = yml.read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("m.pgm", "missing.pgm"))
    with pytest.raises(CalibrationError, match=r"bad\.yaml: image 'missing\.pgm' not found"):
        read_map(bad)
    bad.write_text(text.replace("origin: [-3.0, 2.0, 0.0]", "origin: [1.0, nan]"))
    with pytest.raises(CalibrationError, match=r"bad\.yaml: origin = .*three finite numbers"):
        read_map(bad)
    bad.write_text(text.replace("resolution: 0.05", "resolution: -1"))
    with pytest.raises(CalibrationError, match=r"resolution = -1"):
        read_map(bad)
    m = read_map(yml)
    with pytest.raises(CalibrationError, match="not in open free space"):
        extract_room(m, seed=tuple(m.cell_to_map(np.array([[45, 100]]))[0]))  # inside the table
    out = tmp_path / "room.yaml"
    bad.write_text(text.replace("m.pgm", "missing.pgm"))
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "import_map.py"), str(bad), "--seed", "0", "3",
                           "--out", str(out)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "missing.pgm" in proc.stderr and not out.exists()


def test_cli_writes_room_yaml_and_png(tmp_path):
    yml = write_map(tmp_path)
    m = read_map(yml)
    seed = m.cell_to_map(np.array([[70, 30]]))[0]
    out = tmp_path / "room.yaml"
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "import_map.py"), str(yml), "--seed",
                           *(f"{v:.3f}" for v in seed), "--out", str(out)], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    data = load_yaml(out)
    assert data["world"]["room_size"] == pytest.approx([6.3, 4.3], abs=0.051)
    assert out.with_suffix(".png").is_file()
