"""Measurements for the camera state representations (``tools/bench_camera.py``, docs/benchmarks.md)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ..analysis.frames import frames_hfov
from ..env.gymenv.approach import make_env
from ..env.gymenv.encoded import FrozenEncoder, encoder_camera, low_pass_episodes
from ..params import RobotParams
from ..perception.autoencoding.ae_train import load_autoencoder, read_checkpoint, split_centres
from ..perception.autoencoding.autoencoders import build
from ..perception.autoencoding.keypoints import KeypointDetector, calibrate, encode_keypoints, plane_projection
from ..perception.autoencoding.probe import member_probe, pixel_probe, visible_members
from ..perception.camera import sim_camera
from ..training.config import load_config
from ..training.run import build_model, make_vec_env
from .sim_tracking import SimEvalParams, evaluate_sim


def encoder_fps(arch: str, size: str, batch: int = 64, seconds: float = 3.0) -> float:
    """Frames per second of ``encode`` (eval mode, inference) on random images, best of three timings."""
    model = build(arch, size).eval()
    s = model.size.input_size
    x = torch.rand(batch, 3, s, s)
    best = 0.0
    with torch.inference_mode():
        model.encode(x)
        for _ in range(3):
            n, t0 = 0, time.perf_counter()
            while time.perf_counter() - t0 < seconds / 3:
                model.encode(x)
                n += batch
            best = max(best, n / (time.perf_counter() - t0))
    return best


def render_fps(size: int, frames: int = 600) -> float:
    """Raw TinyRenderer first-person frames per second at ``size`` x ``size`` (robot moving, one scene)."""
    env = make_env(obs_mode="vector")
    env.reset(seed=0)
    world = env.unwrapped.world
    t0 = time.perf_counter()
    for i in range(frames):
        world.render_first_person(size, size)
        _, _, term, trunc, _ = env.step(np.array([0.5, 0.2 * np.sin(i / 10)], np.float32))
        if term or trunc:
            env.reset(seed=i)
    fps = frames / (time.perf_counter() - t0)
    env.close()
    return fps


def training_throughput(encoder: str, obs_mode: str = "camera_speed", policy: str = "ff", steps: int = 4096,
                        n_envs: int = 8) -> float:
    """Env steps per second of PPO training (render + encode + PPO updates) with a frozen encoder."""
    import tempfile

    arch = read_checkpoint(encoder)["arch"]
    res = read_checkpoint(encoder)["resolution"]
    cfg = load_config(None, {"obs_mode": obs_mode, "encoder": arch, "encoder_checkpoint": str(encoder),
                             "camera_size": res, "policy": policy, "n_envs": n_envs})
    venv = make_vec_env(cfg, 0)
    with tempfile.TemporaryDirectory() as tmp:
        model = build_model(cfg, venv, Path(tmp))
        model.learn(cfg.steps_per_update)  # warm-up: one update
        t0 = time.perf_counter()
        model.learn(steps, reset_num_timesteps=False)
        rate = steps / (time.perf_counter() - t0)
    venv.close()
    return rate


def probe_encoders(frames: dict[str, np.ndarray], checkpoints: dict[str, str], mlp: bool = True
                   ) -> dict[str, dict[str, float]]:
    """Linear probe of each encoder's features -> visible members' positions; held-out = validation episodes.
    With ``mlp``, the same rows read by a small MLP too (``NAME_mlp``: whether the features carry the members
    at all; a few minutes on one core)."""
    train_c, val_c = split_centres(frames["episode"], 10)
    members = visible_members(frames)
    n_tr, n_val = len(train_c), len(val_c)
    px = frames["members_px"].astype(float)
    out = {"constant": member_probe(np.zeros((n_tr, 0)), members[train_c], np.zeros((n_val, 0)), members[val_c]),
           "true_torso_pixels": pixel_probe(px[train_c], members[train_c], px[val_c], members[val_c])}
    if mlp:
        out["true_torso_pixels_mlp"] = pixel_probe(px[train_c], members[train_c], px[val_c], members[val_c],
                                                   reader="mlp")
    for name, path in checkpoints.items():
        feats = _encode_all(path, frames["frames"])
        out[name] = member_probe(feats[train_c], members[train_c], feats[val_c], members[val_c])
        out[name]["feature_dim"] = feats.shape[1]
        if mlp:
            out[f"{name}_mlp"] = member_probe(feats[train_c], members[train_c], feats[val_c], members[val_c],
                                              reader="mlp")
    return out


def _encode_all(path: str, images: np.ndarray) -> np.ndarray:
    enc = FrozenEncoder(load_autoencoder(path))
    return np.concatenate([enc.encode(images[i:i + 512]) for i in range(0, len(images), 512)])


def feature_jitter(frames: dict[str, np.ndarray], checkpoints: dict[str, str],
                   alphas: tuple[float, ...] = (1.0, 0.5, 0.3)) -> dict[str, dict[str, Any]]:
    """How much each encoder's features jump between consecutive frames of an episode, against how much they
    vary over the whole file (each feature's standard deviation), as encoded and through the features' low-pass
    (``feature_smoothing`` alpha; 1 = none): the mean absolute first and second differences in those units, and
    the linear probe (held-out median member error, m) on the features the policy would see."""
    episode = np.asarray(frames["episode"])
    same = episode[1:] == episode[:-1]
    same2 = same[1:] & same[:-1]
    train_c, val_c = split_centres(episode, 10)
    members = visible_members(frames)
    out: dict[str, dict[str, Any]] = {}
    for name, path in checkpoints.items():
        raw = _encode_all(path, frames["frames"])
        spread = raw.std(axis=0) + 1e-6
        for alpha in alphas:
            seen = low_pass_episodes(raw, episode, alpha)
            f = seen / spread
            d1 = np.abs(np.diff(f, axis=0))[same]
            d2 = np.abs(f[2:] - 2 * f[1:-1] + f[:-2])[same2]
            probe = member_probe(seen[train_c], members[train_c], seen[val_c], members[val_c])
            out[f"{name}/alpha={alpha:g}"] = {"first_difference": round(float(d1.mean()), 4),
                                              "second_difference": round(float(d2.mean()), 4),
                                              "probe_median_m": probe.get("median_m")}
    return out


def keypoint_tracking(frames: dict[str, np.ndarray], saev: str, episodes: int = 4, steps: int = 150
                      ) -> dict[str, Any]:
    """SAEV keypoint detector calibrated on the training episodes' frames, then the tracker in simulation
    (``sim_tracking.evaluate_sim``, the same drive and scoring as the segmentation and colour detectors)."""
    model = load_autoencoder(saev, arch="saev")
    s = model.size.input_size
    robot = RobotParams(**encoder_camera(saev))  # the camera the encoder learned through
    project = plane_projection(sim_camera(robot, s, s))
    train_c, _ = split_centres(frames["episode"], 10)
    uv, rho = encode_keypoints(model, frames["frames"][train_c])
    calib = calibrate(uv, rho, visible_members(frames)[train_c], project)
    det = KeypointDetector(model, calib, project)
    res = evaluate_sim(SimEvalParams(episodes=episodes, steps=steps, width=s, height=s, detector="saev"),
                       custom=lambda w: det(w.render_first_person(s, s)[0]), robot_params=robot)
    return res | {"calibration": {"keypoints": list(calib.keypoints), "heights_m": list(calib.heights),
                                  "train_median_m": [round(v, 3) for v in calib.train_median_m]}}


def keypoint_precision(frames: dict[str, np.ndarray], noise_px: tuple[float, ...] = (0.0, 0.5, 1.0, 2.0),
                       seed: int = 0) -> dict[str, Any]:
    """What keypoint precision the probe target asks for: the probe (linear and MLP) from each member's true torso
    pixel and from its true foot pixel (where it stands, projected through the frames' camera), each blurred by
    Gaussian noise of ``noise_px`` pixels (seeded); rows ``{torso,feet}_{linear,mlp}_noise{σ}`` over the same
    sightings and split as ``probe_encoders``; ``feet_in_image``: the held-out sightings whose feet are in view
    (a close member's are below the image: this cue is an idealisation there)."""
    train_c, val_c = split_centres(frames["episode"], 10)
    members = visible_members(frames)
    side = frames["frames"].shape[1]
    cam = sim_camera(RobotParams(camera_hfov_deg=frames_hfov(frames)), side, side)
    cues = {"torso": frames["members_px"].astype(float),
            "feet": cam.ground_to_pixel(np.nan_to_num(members.reshape(-1, 2))).reshape(members.shape)}
    rng = np.random.default_rng(seed)
    seen = np.isfinite(members[val_c, :, 0])
    feet = cues["feet"][val_c][seen]
    out: dict[str, Any] = {"feet_in_image": float(np.mean((feet >= 0).all(axis=1) & (feet < side).all(axis=1)))}
    for cue, px in cues.items():
        for sigma in noise_px:
            noisy = px + rng.normal(0.0, sigma, px.shape) if sigma else px
            for reader in ("linear", "mlp"):
                out[f"{cue}_{reader}_noise{sigma:g}"] = pixel_probe(noisy[train_c], members[train_c], noisy[val_c],
                                                                    members[val_c], reader=reader)
    return out
