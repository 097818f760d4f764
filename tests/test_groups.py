"""Groups as real people stand: the F-formation loader, the groups YAML, calibrated and real layouts, and the
social forces holding them."""

import math

import numpy as np
import pytest
import yaml
from scipy.io import savemat

from ssbl_pb.calib.fformations import load_dataset, load_datasets
from ssbl_pb.calib.groups import group_geometry, groups_yaml, real_stats, sim_stats
from ssbl_pb.core.humans import Group
from ssbl_pb.core.layouts import GroupModel, load_group_data, parse_group_data, real_layout, slot_keep
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv, make_env
from ssbl_pb.errors import UserError
from ssbl_pb.params import RobotParams, SocialParams

SOCIAL = SocialParams()
KEEP = slot_keep(SOCIAL, RobotParams().reach, 0.45, 0.15)


def cells(arrays):
    out = np.empty((1, len(arrays)), dtype=object)
    for i, a in enumerate(arrays):
        out[0, i] = a
    return out


def write_dataset(folder, frames, groups, stamps=None, gt_stamps=None, features_key="features"):
    """A dataset folder in the GCFF layout: ``frames`` rows [id, x_cm, y_cm, yaw], ``groups`` lists of id lists."""
    folder.mkdir(parents=True, exist_ok=True)
    stamps = list(range(1, len(frames) + 1)) if stamps is None else stamps
    gt_stamps = stamps[:len(groups)] if gt_stamps is None else gt_stamps
    savemat(folder / "features.mat", {features_key: cells([np.array(f, dtype=float).reshape(-1, 4) for f in frames]),
                                      "timestamp": np.array([stamps])})
    gt = cells([cells([np.array([g], dtype=np.uint8) for g in frame]) for frame in groups])
    savemat(folder / "groundtruth.mat", {"GTgroups": gt, "GTtimestamp": np.array([gt_stamps])})
    return folder


PAIR_AND_TRIO = [[1, 0, 0, 0.0], [2, 80, 0, math.pi], [3, 300, 0, 0.0], [4, 380, 0, 0.0], [5, 340, 70, 0.0]]


def test_loader_reads_positions_in_metres_and_groups(tmp_path):
    folder = write_dataset(tmp_path / "ds", [PAIR_AND_TRIO, PAIR_AND_TRIO[:4] + [[6, 0, 0, 0.0]]],
                           [[[1, 2], [3, 4, 5]], [[1, 2], [3, 4, 5]]])
    ds = load_dataset(folder)
    assert [g.n for g in ds.groups] == [2, 3, 2]  # frame 1's trio lacks member 5: skipped, not an error
    assert ds.skipped == [(1, (3, 4, 5))]
    assert np.allclose(ds.groups[0].xy, [[0.0, 0.0], [0.8, 0.0]]) and ds.quantised  # 0 and pi: multiples of 90
    g = group_geometry(ds.groups[0].xy, ds.groups[0].yaw)
    assert g["centroid_distance_m"] == pytest.approx(0.4) and np.allclose(g["nearest_neighbour_m"], 0.8)
    assert np.allclose(g["orientation_offset_deg"], 0.0)  # they face each other, i.e. their centroid


def test_group_geometry_against_a_hand_computation():
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])  # centroid (1/3, 1/3)
    g = group_geometry(xy, np.array([math.pi / 4, 0.0, 0.0]))
    r = np.array([math.sqrt(2) / 3, math.sqrt(5) / 3, math.sqrt(5) / 3])
    assert g["centroid_distance_m"] == pytest.approx(r.mean())
    assert g["irregularity"] == pytest.approx(r.std() / r.mean())
    assert np.allclose(g["nearest_neighbour_m"], [1.0, 1.0, 1.0])
    # member 0 faces its centroid exactly; member 1 faces +x, its centroid lies at 180 - atan(1/2) deg
    assert g["orientation_offset_deg"][0] == pytest.approx(0.0, abs=1e-9)
    assert g["orientation_offset_deg"][1] == pytest.approx(180 - math.degrees(math.atan(0.5)))


@pytest.mark.parametrize("case, expect", [
    ("missing", "features.mat: file not found"),
    ("keys", "no variable 'features'"),
    ("empty", "is empty"),
    ("unknown_id", "member id(s) [9]"),
    ("columns", "expected finite rows [id, x, y, orientation]"),
    ("stamp", "has no frame in features.mat"),
    ("text", "features.mat: not a readable .mat file (IndexError"),  # a text file named .mat
    ("strings", "'features' frame 0 is not numeric"),
])
def test_loader_rejects_malformed_files_naming_file_and_field(tmp_path, case, expect):
    frames, groups = [PAIR_AND_TRIO], [[[1, 2]]]
    kwargs = {}
    if case == "keys":
        kwargs["features_key"] = "people"
    elif case == "empty":
        frames = [[]]
    elif case == "unknown_id":
        groups = [[[1, 9]]]
    elif case == "columns":
        frames = [[[1, 0, 0], [2, 80, 0]]]
    elif case == "stamp":
        kwargs["gt_stamps"] = [7]
    folder = tmp_path / "ds"
    if case == "missing":
        folder.mkdir()
    elif case == "text":
        write_dataset(folder, frames, groups)
        (folder / "features.mat").write_text("hello world this is text\n")
    elif case == "strings":
        write_dataset(folder, frames, groups)
        savemat(folder / "features.mat", {"features": cells([np.array(["ab"], dtype=object)]),
                                          "timestamp": np.array([[1]])})
    elif case == "columns":
        folder.mkdir()
        savemat(folder / "features.mat", {"features": cells([np.array(frames[0], dtype=float)]),
                                          "timestamp": np.array([[1]])})
        write_dataset(tmp_path / "other", [PAIR_AND_TRIO], groups)
        (tmp_path / "other" / "groundtruth.mat").rename(folder / "groundtruth.mat")
    else:
        write_dataset(folder, frames, groups, **kwargs)
    with pytest.raises(UserError, match="features.mat|groundtruth.mat") as err:
        load_dataset(folder)
    assert expect in str(err.value) and str(folder) in str(err.value)


def test_real_data_loads_with_its_known_dropouts(shared_data):
    ds = {d.name: d for d in load_datasets([shared_data / "fformations"])}
    assert set(ds) == {"CocktailParty", "CoffeeBreak/Seq1", "CoffeeBreak/Seq2"}
    assert len(ds["CocktailParty"].skipped) == 9  # person 202 not located in 9 annotated frames
    assert not ds["CocktailParty"].quantised and ds["CoffeeBreak/Seq1"].quantised
    stats = real_stats(list(ds.values()))
    # SOURCES.md: pairs stand ~0.4 m from their centroid, fives ~0.74 m; nearest members 0.7-1.0 m apart
    assert 0.38 < np.median(stats[2]["centroid_distance_m"]) < 0.46
    assert 0.70 < np.median(stats[5]["centroid_distance_m"]) < 0.78
    assert all(0.65 < np.median(stats[n]["nearest_neighbour_m"]) < 1.0 for n in (2, 3, 4, 5))


def test_shipped_groups_yaml_is_the_calibration_of_the_shared_data(shared_data):
    shipped = load_group_data()
    fresh = parse_group_data(groups_yaml(load_datasets([shared_data / "fformations"])), "fresh")
    assert sorted(shipped.sizes) == sorted(fresh.sizes)
    for n, sd in fresh.sizes.items():
        assert shipped.sizes[n].centroid_distance_m == pytest.approx(sd.centroid_distance_m, abs=1e-4)
        assert len(shipped.sizes[n].layouts) == len(sd.layouts) == sd.groups


def test_calibrated_groups_match_the_real_ones():
    """Per size 2-5, the simulated median member-to-centroid distance within 15 % of the real
    one and the nearest-neighbour spacing within 20 %."""
    data = load_group_data()
    sim = sim_stats(GroupModel("calibrated"), SOCIAL, per_size=300, seed=1)
    for n in (2, 3, 4, 5):
        sd = data.sizes[n]
        real_r = np.interp(50, data.quantiles, sd.centroid_distance_m)
        real_nn = np.interp(50, data.quantiles, sd.nearest_neighbour_m)
        assert abs(np.median(sim[n]["centroid_distance_m"]) / real_r - 1) < 0.15, n
        assert abs(np.median(sim[n]["nearest_neighbour_m"]) / real_nn - 1) < 0.20, n
        assert np.min(sim[n]["nearest_neighbour_m"]) >= 2 * SOCIAL.human_radius - 1e-9  # bodies never overlap
    paper = sim_stats(GroupModel("paper"), SOCIAL, per_size=30)
    for n in (2, 3, 4, 5):  # the paper's circle stays available, about twice as spread
        assert np.median(paper[n]["centroid_distance_m"]) > 1.4 * np.median(sim[n]["centroid_distance_m"])


def real_groups(step=6):
    data = load_group_data()
    return [(n, xy) for n in (2, 3, 4, 5) for xy in data.sizes[n].layouts[::step]]


def one_layout(xy):
    """Group data holding one real layout (the distributions are placeholders)."""
    return parse_group_data({"quantiles": [0, 100], "sizes": {len(xy): {
        "groups": 1, "centroid_distance_m": [1, 1], "nearest_neighbour_m": [1, 1], "irregularity": [0, 0],
        "layouts": [xy.ravel().tolist()]}}}, "one")


@pytest.mark.slow
def test_real_layouts_left_alone_stay_put():
    """A real layout stays where its people stood (<= 0.1 m over 30 s) with the robot at its nearest start
    (2.5 m); the SFFM with the paper's single ring and 1.2 m personal zone pushes the same groups apart."""
    rng = np.random.default_rng(0)
    robot = np.array([2.5, 0.0])
    worst, worst_paper = 0.0, 0.0
    for n, xy in real_groups(step=10):
        lay = real_layout(n, one_layout(xy), rng)
        for paper in (False, True):
            g = Group(SOCIAL, np.zeros(2), lay, KEEP)
            if paper:  # one o-space radius for all, members repel within the personal zone
                g.ring_offset[:] = 0.0
                g.comfort[:] = SOCIAL.personal_radius
            start = g.pos.copy()
            for _ in range(300):
                g.step(robot, 0.1)
            drift = float(np.hypot(*(g.pos - start).T).max())
            if paper:
                worst_paper = max(worst_paper, drift)
            else:
                worst = max(worst, drift)
    assert worst <= 0.1  # measured 0.02 m (a group of 5 whose place is 1.4 m out feels the robot at 2.5 m)
    assert worst_paper > 0.3  # measured 1.1 m


def test_real_groups_open_a_place_for_the_robot():
    """A robot standing at its place (outside the ring, keeping the intimate zone and a margin from the corner of
    its footprint to every member): the group widens its ring, no member comes closer, the place stays put."""
    rng = np.random.default_rng(1)
    for n, xy in real_groups(step=12):
        g = Group(SOCIAL, np.zeros(2), real_layout(n, one_layout(xy), rng), KEEP)
        robot = g.free_slot()
        near0, ring0 = np.hypot(*(g.pos - robot).T).min(), np.hypot(*g.pos.T)
        assert near0 == pytest.approx(KEEP, abs=1e-6) and g.join_radius == pytest.approx(np.hypot(*robot))
        for _ in range(100):
            g.step(robot, 0.1)
        assert g.join_weight > 0.999 and g.radius > g.base_radius  # joined: the ring widened ...
        assert np.all(np.hypot(*g.pos.T) - ring0 > 0.015)  # ... every member stepped back from the centre ...
        assert np.hypot(*(g.pos - robot).T).min() > near0 - 0.01  # ... none toward the robot
        assert np.abs(g.vel).max() < 0.05
        assert np.hypot(*(g.free_slot(robot) - robot)) < 0.1  # the place stays where the robot stands


def test_real_scenario_places_members_as_annotated():
    data = load_group_data()
    env = ApproachGroupEnv(scenario="real")
    sizes = set()
    for seed in range(12):
        _, info = env.reset(seed=seed)
        assert info["formation"] == "real"
        pos = env.world.group.pos
        d = np.sort(np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1)).ravel())
        n = len(pos)
        sizes.add(n)
        # the same pairwise distances as one of the annotated groups (rotation and translation keep them)
        ok = any(np.allclose(d, np.sort(np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1)).ravel()), atol=1e-9)
                 for xy in data.sizes[n].layouts)
        assert ok
        assert np.allclose(env.world.group.centre0, pos.mean(axis=0))  # re-centred on the centroid
    assert sizes <= {2, 3, 4, 5} and len(sizes) >= 3
    env.close()
    from ssbl_pb.env.rooms.scenarios import ScenarioMix

    assert "real" in {f for sc in ScenarioMix("mixed").members for f in sc.formations}


def test_groups_yaml_is_validated_naming_file_and_field(tmp_path):
    good = {"quantiles": [0, 50, 100], "sizes": {2: {"groups": 3, "centroid_distance_m": [0.3, 0.4, 0.5],
                                                     "nearest_neighbour_m": [0.6, 0.8, 1.0],
                                                     "irregularity": [0, 0, 0]}}}
    path = tmp_path / "g.yaml"

    def check(data, expect):
        path.write_text(yaml.safe_dump(data))
        with pytest.raises(UserError) as err:
            make_env(scenario="default", groups_yaml=str(path))
        assert str(path) in str(err.value) and expect in str(err.value), str(err.value)

    bad = yaml.safe_load(yaml.safe_dump(good))
    bad["sizes"][2]["centroid_distance_m"] = [-0.1, 0.4, 0.5]
    check(bad, "sizes.2.centroid_distance_m")
    bad = yaml.safe_load(yaml.safe_dump(good))
    del bad["sizes"][2]["nearest_neighbour_m"]
    check(bad, "sizes.2.nearest_neighbour_m: missing")
    check({"quantiles": [0, 100], "sizes": {}}, "sizes: missing or empty")
    path.write_text(yaml.safe_dump(good))
    env = make_env(scenario="default", groups_yaml=str(path))  # pairs only: enough for the default scenario
    env.reset(seed=0)
    assert 0.3 <= np.hypot(*(env.unwrapped.world.group.pos[0] - env.unwrapped.world.group.pos[1])) / 2 <= 0.5
    env.close()
    with pytest.raises(UserError, match=r"sizes\.3: missing"):
        make_env(scenario="circular", groups_yaml=str(path))
    with pytest.raises(UserError, match=r"sizes\.2\.layouts: empty"):
        make_env(scenario="real-2", groups_yaml=str(path))
    with pytest.raises(UserError, match="groups = 'blob'"):
        ApproachGroupEnv(groups="blob")


def test_calibrate_groups_tool_writes_yaml_figure_and_table(tmp_path):
    from test_contracts import run_tool

    write_dataset(tmp_path / "data" / "a", [PAIR_AND_TRIO] * 3, [[[1, 2], [3, 4, 5]]] * 3)
    out = tmp_path / "res" / "groups.yaml"
    res = run_tool("calibrate_groups.py", [str(tmp_path / "data"), "--out", str(out), "--per-size", "40"])
    assert res.returncode == 0, res.stderr
    data = load_group_data(out)
    assert sorted(data.sizes) == [2, 3] and data.sizes[2].groups == 3
    assert data.sizes[2].centroid_distance_m[0] == pytest.approx(0.4)
    assert out.with_suffix(".png").stat().st_size > 10_000
    table = out.with_suffix(".md").read_text()
    assert "| a | 6 | 0 | quantised, not used |" in table and "| 2 | 3 | 0.40 / " in table
    # a malformed dataset: one line naming the file and field, and nothing written
    write_dataset(tmp_path / "data" / "b", [PAIR_AND_TRIO], [[[1, 9]]])
    out2 = tmp_path / "res2" / "groups.yaml"
    res = run_tool("calibrate_groups.py", [str(tmp_path / "data"), "--out", str(out2)])
    assert res.returncode == 2 and "groundtruth.mat: 'GTgroups' frame 0: member id(s) [9]" in res.stderr
    assert not (tmp_path / "res2").exists()


def test_calibrate_groups_given_a_file_says_it_wants_the_dataset_folder(tmp_path):
    from test_contracts import run_tool

    write_dataset(tmp_path / "data" / "a", [PAIR_AND_TRIO] * 3, [[[1, 2], [3, 4, 5]]] * 3)
    given = tmp_path / "data" / "a" / "features.mat"
    res = run_tool("calibrate_groups.py", [str(given), "--out", str(tmp_path / "res" / "groups.yaml")])
    assert res.returncode == 2 and res.stderr.splitlines() == [
        f"error: {given}: a file; expected a dataset folder holding features.mat and groundtruth.mat, or a folder "
        f"above such folders (layout in shared/data/fformations/SOURCES.md): give its folder, {given.parent}"]
    assert not (tmp_path / "res").exists()
