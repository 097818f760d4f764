"""Frames files, autoencoder training and checkpoints (analysis/frames.py, ae_train.py,
tools/train_ae.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from ssbl_pb.analysis.frames import (
    FramesError,
    collect,
    frames_hfov,
    load_frames,
    save_frames,
)
from ssbl_pb.errors import UserError
from ssbl_pb.perception.autoencoding import autoencoders as A
from ssbl_pb.perception.autoencoding.ae_losses import LossWeights, triplet_centres
from ssbl_pb.perception.autoencoding.ae_train import (
    AETrainParams,
    CheckpointError,
    load_autoencoder,
    save_checkpoint,
    split_centres,
    train_autoencoder,
)

TINY = A.AESize("tiny", 24, (4, 6, 5), (3, 3, 3), 2, 12, (4, 4), 8, 6)


def moving_square(n_episodes: int = 6, length: int = 20, size: int = 24, seed: int = 0) -> dict[str, np.ndarray]:
    """Synthetic frames: a red square sliding across a grey background, one direction per episode."""
    rng = np.random.default_rng(seed)
    frames, episode = [], []
    for e in range(n_episodes):
        start, step = rng.integers(0, size - 6, 2), rng.choice([-1, 1], 2)
        for t in range(length):
            img = np.full((size, size, 3), 120, np.uint8)
            r, c = np.clip(start + step * t // 2, 0, size - 6)
            img[r:r + 6, c:c + 6] = (220, 30, 30)
            frames.append(img)
            episode.append(e)
    n = len(frames)
    nan = np.full((n, 5, 2), np.nan, np.float32)
    return {"frames": np.asarray(frames), "episode": np.asarray(episode, np.int32),
            "speed": np.zeros((n, 2), np.float32), "members_rel": nan, "members_px": nan.copy(),
            "policy": np.zeros(n, np.int8), "policies": np.asarray(["random"])}


def test_triplets_stay_inside_episodes() -> None:
    ep = np.array([0, 0, 0, 1, 1, 2, 2, 2, 2])
    assert triplet_centres(ep).tolist() == [1, 6, 7]
    train, val = split_centres(np.repeat(np.arange(10), 4), 10)
    assert set(val.tolist()) == {37, 38} and not set(train.tolist()) & {37, 38}


def test_collect_frames_records_members_and_their_pixels() -> None:
    data = collect(2, 32, seed=3, policies=("straight", "sffm"), scenario="default")
    n = len(data["frames"])
    assert data["frames"].shape == (n, 32, 32, 3) and data["frames"].dtype == np.uint8
    assert set(np.unique(data["episode"])) == {0, 1} and np.all(np.diff(data["episode"]) >= 0)
    assert data["policies"].tolist() == ["straight", "sffm"]
    rel = data["members_rel"]
    assert np.isfinite(rel[:, :2]).all() and np.isnan(rel[:, 2:]).all()  # two members, three empty slots
    px = data["members_px"]
    seen = np.isfinite(px[..., 0])
    assert seen[:, :2].mean() > 0.5 and not seen[:, 2:].any()  # both policies turn toward the group
    assert np.all((px[seen] > -0.5) & (px[seen] < 31.5))
    assert np.all(rel[seen][:, 0] > 0)  # a visible member is in front of the camera
    assert np.abs(data["speed"]).max() <= 1.01


def test_a_narrower_camera_magnifies_the_members() -> None:
    """The same drive through Pepper's 56.3 deg camera and the paper's 26.5 deg one: a member's offset from the
    image centre grows by tan(28.15 deg) / tan(13.25 deg) = 2.27 (pinhole), and the file keeps the camera."""
    wide = collect(1, 32, seed=3, policies=("straight",), scenario="default")
    narrow = collect(1, 32, seed=3, policies=("straight",), scenario="default", camera_hfov_deg=26.5)
    assert frames_hfov(wide) == pytest.approx(56.3) and frames_hfov(narrow) == pytest.approx(26.5)
    assert np.array_equal(wide["members_rel"], narrow["members_rel"], equal_nan=True)  # the same drive
    both = np.isfinite(wide["members_px"][..., 0]) & np.isfinite(narrow["members_px"][..., 0])
    off_w, off_n = wide["members_px"][both] - 16.0, narrow["members_px"][both] - 16.0  # centre: W / 2
    big = np.abs(off_w) > 1.0
    assert big.sum() > 20
    ratio = np.tan(np.radians(56.3 / 2)) / np.tan(np.radians(26.5 / 2))
    assert np.allclose(off_n[big] / off_w[big], ratio, rtol=0.02)
    assert frames_hfov({k: v for k, v in wide.items() if k != "camera_hfov"}) == pytest.approx(56.3)  # older files


def test_frames_file_checks_name_the_problem(tmp_path: Path) -> None:
    data = moving_square(2, 5)
    good = save_frames(tmp_path / "f.npz", data)
    assert load_frames(good, 24)["frames"].shape == (10, 24, 24, 3)
    with pytest.raises(FramesError, match="frames are 24x24, the encoder takes 64x64"):
        load_frames(good, 64)
    bad = {k: v for k, v in data.items() if k != "speed"}
    save_frames(tmp_path / "b.npz", bad)
    with pytest.raises(FramesError, match=r"missing key\(s\) \['speed'\]"):
        load_frames(tmp_path / "b.npz")
    save_frames(tmp_path / "c.npz", data | {"frames": data["frames"][..., 0]})
    with pytest.raises(FramesError, match="'frames' has shape"):
        load_frames(tmp_path / "c.npz")
    save_frames(tmp_path / "e.npz", data | {"camera_hfov": np.array([26.5, 26.5])})
    with pytest.raises(FramesError, match="'camera_hfov' has shape"):
        load_frames(tmp_path / "e.npz")
    (tmp_path / "d.npz").write_text("not a zip")
    with pytest.raises(FramesError, match=r"d.npz: not a frames file written by tools/collect_frames.py .*; this is "
                                          r"not an .npz \(zip\) archive\)"):
        load_frames(tmp_path / "d.npz")


def test_a_run_resumed_from_its_snapshot_ends_as_an_uninterrupted_one(tmp_path: Path) -> None:
    import dataclasses

    torch.set_num_threads(1)
    data = moving_square(12, 8)
    params = AETrainParams(steps=12, batch=4, lr=3e-3, eval_every=4, val_every_episode=4)
    saved: dict[int, Path] = {}

    def keep(step: int, m: A.Autoencoder, state: dict) -> None:
        saved[step] = save_checkpoint(tmp_path / f"s{step}.pt", m, {"step": step, "resume": state})

    whole, history = train_autoencoder(data, "saev", TINY, params, on_eval=keep)
    resumed, history2 = train_autoencoder(data, "saev", TINY, params, resume=saved[4])
    for (name, a), b in zip(whole.state_dict().items(), resumed.state_dict().values(), strict=True):
        assert torch.equal(a, b), name  # weights, BatchNorm statistics: dropout and batches replayed exactly
    assert [r["step"] for r in history2] == [4, 8, 12] and history2[-1]["val_total"] == history[-1]["val_total"]
    with pytest.raises(CheckpointError, match=r"--resume \S*s4.pt: lr is 0.003, this run's is 0.001"):
        train_autoencoder(data, "saev", TINY, dataclasses.replace(params, lr=1e-3), resume=saved[4])
    weights_differ = r"loss weights is \{.*'smoothness': 0.001.*\}, this run's is \{.*'smoothness': 0.05"
    with pytest.raises(CheckpointError, match=weights_differ):
        train_autoencoder(data, "saev", TINY, dataclasses.replace(params, weights=LossWeights(smoothness=0.05)),
                          resume=saved[4])
    with pytest.raises(CheckpointError, match="architecture is 'saev', this run's is 'conv'"):
        train_autoencoder(data, "conv", TINY, params, resume=saved[4])
    with pytest.raises(CheckpointError, match="number of frames is 96, this run's is 80"):
        train_autoencoder(moving_square(10, 8), "saev", TINY, params, resume=saved[4])
    with pytest.raises(CheckpointError, match="already at step 8, --steps is 8"):
        train_autoencoder(data, "saev", TINY, dataclasses.replace(params, steps=8), resume=saved[8])
    with pytest.raises(CheckpointError, match="holds no training state"):
        train_autoencoder(data, "saev", TINY, params, resume=save_checkpoint(tmp_path / "plain.pt", whole))


@pytest.mark.parametrize("arch", A.ARCHS)
def test_training_lowers_the_held_out_reconstruction_error(arch: str) -> None:
    torch.set_num_threads(1)
    params = AETrainParams(steps=80, batch=8, lr=3e-3, eval_every=20, val_every_episode=4)
    probe, seen = torch.rand(2, 3, 24, 24), []

    def on_eval(step: int, m: A.Autoencoder, state: dict) -> None:
        with torch.inference_mode():
            seen.append((step, m.training, m.encode(probe).clone()))

    model, history = train_autoencoder(moving_square(40, 8), arch, TINY, params, on_eval=on_eval)
    assert not model.training
    assert [(s, t) for s, t, _ in seen] == [(20, False), (40, False), (60, False), (80, False)]
    with torch.inference_mode():
        assert torch.equal(seen[-1][2], model.encode(probe)) and not torch.equal(seen[0][2], seen[-1][2])
    first, last = history[0]["val_reconstruction"], history[-1]["val_reconstruction"]
    assert last < 0.7 * first, [round(r["val_reconstruction"], 4) for r in history]
    assert [r["step"] for r in history] == [20, 40, 60, 80]


def test_a_larger_smoothness_weight_steadies_the_keypoints() -> None:
    torch.set_num_threads(1)
    data = moving_square(24, 8)
    jitter = {}
    for w in (0.0, 5.0):
        params = AETrainParams(steps=40, batch=8, lr=3e-3, eval_every=20, val_every_episode=4,
                               weights=LossWeights(smoothness=w))
        jitter[w] = train_autoencoder(data, "saev", TINY, params)[1][-1]["val_smoothness"]
    assert jitter[5.0] < 0.5 * jitter[0.0], jitter
    with pytest.raises(UserError, match=r"--smoothness-weight -1.0: expected a finite number >= 0"):
        LossWeights(smoothness=-1.0)


def test_checkpoint_round_trip_and_checks(tmp_path: Path) -> None:
    torch.manual_seed(1)
    model = A.build("saev", TINY).eval()
    path = save_checkpoint(tmp_path / "enc.pt", model, {"note": 1})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["enc.pt"]  # no temporary file left
    again = load_autoencoder(path, "saev", "tiny", 24)
    x = torch.rand(2, 3, 24, 24)
    with torch.inference_mode():
        assert torch.equal(model.encode(x), again.encode(x))
    with pytest.raises(CheckpointError, match="architecture is 'saev', expected 'conv'"):
        load_autoencoder(path, arch="conv")
    with pytest.raises(CheckpointError, match="size is 'tiny', expected 'cpu'"):
        load_autoencoder(path, size="cpu")
    with pytest.raises(CheckpointError, match="input resolution is 24, expected 64"):
        load_autoencoder(path, resolution=64)
    (tmp_path / "cut.pt").write_bytes(path.read_bytes()[:100])
    with pytest.raises(CheckpointError, match="unreadable"):
        load_autoencoder(tmp_path / "cut.pt")
    with pytest.raises(CheckpointError, match="file not found"):
        load_autoencoder(tmp_path / "none.pt")


@pytest.mark.slow
def test_train_ae_tool_writes_checkpoint_and_figures(tmp_path: Path) -> None:
    from tests.test_contracts import run_tool

    data = moving_square(10, 12, size=64)
    save_frames(tmp_path / "f.npz", data)
    args = ["--frames", str(tmp_path / "f.npz"), "--arch", "saev", "--steps", "3", "--batch", "4", "--threads", "1",
            "--snapshot-every", "2"]
    res = run_tool("train_ae.py", [*args, "--out", str(tmp_path / "ae")])
    assert res.returncode == 0, res.stderr
    names = sorted(p.name for p in (tmp_path / "ae").iterdir())
    assert names == ["encoder.pt", "history.csv", "keypoints.png", "losses.png", "reconstructions.png",
                     "snapshots", "summary.json"]
    assert [p.name for p in (tmp_path / "ae" / "snapshots").iterdir()] == ["encoder_step2.pt"]
    assert load_autoencoder(tmp_path / "ae" / "snapshots" / "encoder_step2.pt", "saev", "cpu", 64)
    assert load_autoencoder(tmp_path / "ae" / "encoder.pt", "saev", "cpu", 64).feature_dim == 48
    snap = tmp_path / "ae" / "snapshots" / "encoder_step2.pt"
    res = run_tool("train_ae.py", [*args, "--out", str(tmp_path / "again"), "--resume", str(snap)])
    assert res.returncode == 0, res.stderr
    whole, resumed = (torch.load(tmp_path / d / "encoder.pt", weights_only=True)["state_dict"] for d in ("ae", "again"))
    assert all(torch.equal(whole[k], resumed[k]) for k in whole)


@pytest.mark.slow
def test_interrupted_train_ae_keeps_its_snapshots(tmp_path: Path) -> None:
    import signal
    import subprocess
    import sys
    import time

    from tests.test_contracts import ROOT

    save_frames(tmp_path / "f.npz", moving_square(10, 12, size=64))
    out = tmp_path / "runs" / "ae"
    proc = subprocess.Popen([sys.executable, str(ROOT / "tools" / "train_ae.py"), "--frames", str(tmp_path / "f.npz"),
                             "--arch", "saev", "--steps", "100000", "--batch", "2", "--snapshot-every", "250",
                             "--threads", "1", "--out", str(out)], cwd=ROOT, stderr=subprocess.PIPE, text=True)
    first = out / "snapshots" / "encoder_step250.pt"
    deadline = time.monotonic() + 120
    while not first.is_file() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert "snapshots kept" in err and not (out / "encoder.pt").exists()
    assert f"continue with: python tools/train_ae.py --frames {tmp_path / 'f.npz'} --arch saev" in err
    assert f"--resume {out / 'snapshots'}/encoder_step" in err
    assert load_autoencoder(first, "saev", "cpu", 64).feature_dim == 48
    assert not [p for p in (out / "snapshots").iterdir() if p.name.startswith(".")]  # no temporary file left


def _tool(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    """``tools/train_ae.py`` in this process under ``cli.run``: (exit code, non-empty stderr lines)."""
    from tests.test_training_safety import exit_code

    return exit_code("train_ae.py", argv, capsys)


def test_too_few_episodes_to_hold_one_out_is_an_error_naming_how_many(tmp_path: Path, capsys) -> None:
    with pytest.raises(UserError, match=r"hold 4 episode\(s\) .* none is held out .* collect at least 10 episodes"):
        split_centres(np.repeat(np.arange(4), 5), 10)
    with pytest.warns(UserWarning, match="validating on the training episodes"):  # library callers: a warning
        train, val = split_centres(np.repeat(np.arange(4), 5), 10, strict=False)
    assert np.array_equal(train, val)
    save_frames(tmp_path / "f.npz", moving_square(4, 5, size=64))
    code, err = _tool(["--frames", str(tmp_path / "f.npz"), "--arch", "saev", "--out", str(tmp_path / "ae")], capsys)
    assert code == 2 and len(err) == 1 and "f.npz: the frames hold 4 episode(s)" in err[0], err
    assert not (tmp_path / "ae").exists()


def test_a_truncated_frames_file_is_one_line(tmp_path: Path, capsys) -> None:
    whole = save_frames(tmp_path / "f.npz", moving_square(10, 5, size=64)).read_bytes()
    for name, data in (("cut.npz", whole[: len(whole) // 2]), ("tail.npz", whole[:-40])):
        (tmp_path / name).write_bytes(data)
        code, err = _tool(["--frames", str(tmp_path / name), "--arch", "saev", "--out", str(tmp_path / "ae")],
                          capsys)
        assert code == 2 and len(err) == 1 and (f"--frames {tmp_path / name}: not a frames file written by "
                                                "tools/collect_frames.py") in err[0], err
        assert "this is a damaged or cut-short .npz archive" in err[0], err
    assert not (tmp_path / "ae").exists()


@pytest.mark.parametrize("content, what", [(b"episode,frame\n1,2\n", "not an .npz (zip) archive"),
                                           (None, "a single .npy array")])
def test_a_file_that_is_not_a_frames_archive_is_one_line_saying_what_was_expected(tmp_path, capsys, content, what):
    """A text file or a lone .npy named .npz: what was expected and what it is, not numpy's advice (pickles)."""
    path = tmp_path / "frames.npz"
    if content is None:
        with open(path, "wb") as fh:
            np.save(fh, np.zeros((4, 64, 64, 3), np.uint8))
    else:
        path.write_bytes(content)
    code, err = _tool(["--frames", str(path), "--arch", "saev", "--out", str(tmp_path / "ae")], capsys)
    assert code == 2 and len(err) == 1, err
    assert err[0] == (f"error: --frames {path}: not a frames file written by tools/collect_frames.py (expected an "
                      f".npz archive of the arrays ['episode', 'frames', 'members_px', 'members_rel', 'policies', "
                      f"'policy', 'speed']; this is {what})"), err
    assert "pickle" not in err[0] and not (tmp_path / "ae").exists()


def test_resume_errors_name_the_flag_and_come_before_any_work(tmp_path: Path, capsys) -> None:
    import dataclasses

    save_frames(tmp_path / "f.npz", moving_square(10, 5, size=64))
    params = AETrainParams(steps=20, batch=4, eval_every=2)
    state = {"step": 2, "params": {k: getattr(params, k) for k in ("batch", "lr", "eval_every", "val_every_episode",
                                                                  "seed")},
             "frames": 50, "weights": dataclasses.asdict(LossWeights())}
    snap = save_checkpoint(tmp_path / "snap.pt", A.build("saev", "cpu"), {"step": 2, "resume": state})
    (tmp_path / "cut.pt").write_bytes(snap.read_bytes()[:200])
    args = ["--frames", str(tmp_path / "f.npz"), "--arch", "saev", "--steps", "20", "--batch", "4",
            "--out", str(tmp_path / "ae")]
    for resume, expect in ((snap, "lr is 0.001, this run's is 0.01"), (tmp_path / "cut.pt", "unreadable")):
        code, err = _tool([*args, "--lr", "0.01", "--resume", str(resume)], capsys)
        assert code == 2 and len(err) == 1 and err[0].startswith(f"error: --resume {resume}: {expect}"), err
    assert not (tmp_path / "ae").exists()


def test_ctrl_c_keeps_the_snapshots_and_prints_the_resume_command(tmp_path: Path, capsys, monkeypatch) -> None:
    import ssbl_pb.perception.autoencoding.ae_train as T

    def interrupted(data, arch, size, params, progress=None, on_eval=None, resume=None):
        on_eval(params.eval_every, A.build(arch, size).eval(), {})
        raise KeyboardInterrupt

    monkeypatch.setattr(T, "train_autoencoder", interrupted)
    save_frames(tmp_path / "f.npz", moving_square(10, 5, size=64))
    out = tmp_path / "ae"
    code, err = _tool(["--frames", str(tmp_path / "f.npz"), "--arch", "saev", "--steps", "20", "--snapshot-every",
                       "2", "--out", str(out)], capsys)
    assert code == 130, err
    snap = out / "snapshots" / "encoder_step2.pt"
    assert snap.is_file() and not (out / "encoder.pt").exists()
    assert (f"continue with: python tools/train_ae.py --frames {tmp_path / 'f.npz'} --arch saev --steps 20 "
            f"--snapshot-every 2 --out {out} --resume {snap}") in err[0], err


def test_load_frames_refuses_a_truncated_archive_for_every_caller(tmp_path: Path) -> None:
    from ssbl_pb.analysis.frames import FramesError, load_frames

    whole = save_frames(tmp_path / "f.npz", moving_square(10, 5, size=64)).read_bytes()
    (tmp_path / "tail.npz").write_bytes(whole[:-40])  # bench_camera and Table I read frames this way too
    with pytest.raises(FramesError, match="tail.npz: not a frames file written by tools/collect_frames.py"):
        load_frames(tmp_path / "tail.npz")
