"""Markdown and PNG reports for the camera and dynamics calibrations (figures a reviewer asks for)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..files import write_text
from ..params import RobotParams
from .dynamics import NAMES, DynamicsResult, simulate_axis
from .dynamics_log import AXES, DynamicsLog, body_velocity_from_pose, simulate_log
from .humans import summary
from .intrinsics import IntrinsicsResult
from .io import save_figure, write_image


def _tile(img: np.ndarray, title: str) -> np.ndarray:
    img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img.copy()
    cv2.putText(img, title, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 255), 2, cv2.LINE_AA)
    return img


def intrinsics_figure(res: IntrinsicsResult, board: tuple[int, int], path: str | Path) -> Path:
    """2x2 PNG: corners on the first and the worst image, the first image raw and undistorted."""
    det = res.detections
    worst = int(np.argmax(res.per_image))
    tiles = []
    for i in (0, worst):
        img = cv2.cvtColor(cv2.imread(str(det.paths[i]), cv2.IMREAD_GRAYSCALE), cv2.COLOR_GRAY2BGR)
        cv2.drawChessboardCorners(img, board, det.corners[i].reshape(-1, 1, 2), True)
        tiles.append(_tile(img, f"{det.paths[i].name}: {res.per_image[i]:.2f} px"))
    raw = cv2.imread(str(det.paths[0]), cv2.IMREAD_GRAYSCALE)
    cam = res.camera
    und = cv2.undistort(raw, cam.K, cam.dist)
    tiles += [_tile(raw, "raw"), _tile(und, "undistorted")]
    grid = np.vstack([np.hstack(tiles[:2]), np.hstack(tiles[2:])])
    return write_image(path, grid)


def intrinsics_markdown(res: IntrinsicsResult, command: str, stability: np.ndarray | None = None,
                        k_out: int = 3) -> str:
    """The camera report: intrinsics with 1-sigma, RMS, per-image errors, rejected images, stability."""
    cam, std = res.camera, res.std_intrinsics
    hfov, vfov = cam.fov_deg()
    fx_std = std[1] if std[0] == 0 else std[0]  # fx is tied to fy when the aspect ratio is fixed
    lines = [f"# Camera calibration: {cam.name}", "", f"Command: `{command}`", "",
             f"- images used: {len(res.per_image)}, rejected: {len(res.detections.rejected)}",
             f"- RMS reprojection error: **{res.rms:.3f} px** (per image: median {np.median(res.per_image):.3f}, "
             f"max {res.per_image.max():.3f})",
             f"- image size {cam.width}x{cam.height}, field of view {hfov:.1f} x {vfov:.1f} deg", "",
             "| parameter | value | 1-sigma |", "|---|---|---|",
             f"| fx | {cam.fx:.2f} | {fx_std:.2f} |", f"| fy | {cam.fy:.2f} | {std[1]:.2f} |",
             f"| cx | {cam.cx:.2f} | {std[2]:.2f} |", f"| cy | {cam.cy:.2f} | {std[3]:.2f} |"]
    for i, name in enumerate(("k1", "k2", "p1", "p2", "k3")):
        if i < len(cam.dist):
            lines.append(f"| {name} | {cam.dist[i]:.5f} | {std[4 + i]:.5f} |")
    if stability is not None and len(stability):
        worst = np.abs(stability).max(axis=0) * 100
        lines += ["", f"Leave-{k_out}-out stability over {len(stability)} subsets (largest change from the "
                  "full-set value): " + ", ".join(f"{n} {w:.2f} %" for n, w in zip(("fx", "fy", "cx", "cy"), worst,
                                                                                   strict=True))]
    lines += ["", "| image | RMS error (px) |", "|---|---|"]
    lines += [f"| {p.name} | {e:.3f} |" for p, e in zip(res.detections.paths, res.per_image, strict=True)]
    if res.detections.rejected:
        lines += ["", "Rejected:", ""] + [f"- {p}: {why}" for p, why in res.detections.rejected]
    return "\n".join(lines) + "\n"


def dynamics_figure(log: DynamicsLog, res: DynamicsResult, params: RobotParams, path: str | Path) -> Path:
    """Commanded, measured and simulated velocity per axis (simulated: per-axis fit and HolonomicBase)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    _, pose = simulate_log(params, log.cmd, log.dt)
    base_vel = body_velocity_from_pose(log.t, pose)
    fig, axes = plt.subplots(len(AXES), 1, figsize=(11, 8), sharex=True)
    units = {"vx": "m/s", "vy": "m/s", "wz": "rad/s"}
    for j, (ax, name) in enumerate(zip(axes, AXES, strict=True)):
        ax.step(log.t, log.cmd[:, j], where="post", color="0.6", lw=1, label="commanded")
        ax.plot(log.t, log.vel[:, j], ".", ms=1.5, color="tab:blue", label="measured")
        if name in res.fits:
            f = res.fits[name]
            lo, hi = f.window
            model = simulate_axis(log.t[lo:hi], log.cmd[lo:hi, j], f.theta, window_mean=log.from_pose)
            ax.plot(log.t[lo:hi], model, color="tab:red", lw=1, label=f"per-axis fit (rms {f.rms:.3f})")
        ax.plot(log.t, base_vel[:, j], color="tab:green", lw=0.8, ls="--", label="HolonomicBase, fitted params")
        ax.set_ylabel(f"{name} ({units[name]})")
        ax.legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"Base dynamics: {Path(log.path).name}")
    return save_figure(path, fig)


def dynamics_markdown(log: DynamicsLog, res: DynamicsResult, command: str,
                      truth: dict[str, float] | None = None) -> str:
    """Per-axis fitted constants with 1-sigma and residuals, and the RobotParams fields written."""
    lines = [f"# Base dynamics identification: {Path(log.path).name}", "", f"Command: `{command}`", "",
             f"{len(log.t)} rows, {log.t[-1]:.1f} s, step {log.dt * 1000:.1f} ms, velocity from "
             f"{'odometry poses (central differences)' if log.from_pose else 'odometry velocities'}.", "",
             "| axis | latency (s) | time constant (s) | accel limit | speed limit | residual RMS | rows |",
             "|---|---|---|---|---|---|---|"]
    for name, f in res.fits.items():
        # a zero sigma means the cost was flat in that parameter at the optimum (no gradient), not certainty
        cells = [f"{v:.4f} ± {s:.4f}" if s > 1e-6 else f"{v:.4f} (flat)" for v, s in zip(f.theta, f.std, strict=True)]
        if not f.identified["max_accel"]:
            cells[2] += " (not identified)"
        if not f.identified["max_speed"]:
            cells[3] += " (not identified)"
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {f.rms:.4f} | {f.window[0]}-{f.window[1]} |")
    lines += ["", "RobotParams fields written:", "", "| field | value |" + (" truth | error |" if truth else ""),
              "|---|---|" + ("---|---|" if truth else "")]
    for k, v in res.params.items():
        row = f"| {k} | {v:.4f} |"
        if truth and k in truth:
            err = f"{100 * (v - truth[k]) / truth[k]:+.1f} %" if truth[k] else f"{v - truth[k]:+.4f}"
            row += f" {truth[k]:.4f} | {err} |"
        lines.append(row)
    if res.notes:
        lines += ["", "Notes:", ""] + [f"- {n}" for n in res.notes]
    lines += ["", f"Fitted per axis: {', '.join(NAMES)} (accel and speed limits in m/s^2 and m/s for vx/vy, "
              "rad/s^2 and rad/s for wz). HolonomicBase rounds the latency to whole control periods."]
    return "\n".join(lines) + "\n"


def write_markdown(path: str | Path, text: str) -> Path:
    return write_text(path, text)


HUMAN_STATS = (("group_distance", "group: nearest-member distance (m)", (0, 3)),
               ("walking_speed", "speed while moving (m/s)", (0, 2.5)),
               ("stranger_distance", "stranger closest approach (m)", (0, 3)))


def humans_figure(real: dict[str, np.ndarray], sims: dict[str, dict[str, np.ndarray]], path: str | Path) -> Path:
    """Real vs simulated histograms (density), one panel per statistic."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    for ax, (key, label, rng) in zip(axes, HUMAN_STATS, strict=True):
        bins = np.linspace(*rng, 41)
        ax.hist(np.clip(real[key], *rng), bins=bins, density=True, alpha=0.5, color="tab:blue", label="ETH/UCY")
        for (name, sim), colour in zip(sims.items(), ("tab:red", "tab:green"), strict=False):
            ax.hist(np.clip(sim[key], *rng), bins=bins, density=True, histtype="step", lw=1.5, color=colour,
                    label=f"SFFM {name}")
        ax.set_xlabel(label)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("density")
    return save_figure(path, fig)


def humans_markdown(real: dict[str, dict[str, np.ndarray]], sims: dict[str, dict[str, np.ndarray]],
                    fields: dict[str, float], notes: list[str], command: str) -> str:
    """Table of median [quartiles] (count) per scene and for the simulations; fitted fields and reasons."""
    head = "| source | " + " | ".join(label for _, label, _ in HUMAN_STATS) + " |"
    lines = ["# Human motion: ETH/UCY against the social force model", "", f"Command: `{command}`", "",
             "Median [25 %, 75 %] (count). ETH/UCY groups walk together; the SFFM groups stand in conversation, "
             "so their member distances are not expected to match; speeds compare walking with repositioning.",
             "", head, "|---|---|---|---|"]
    for name, st in real.items():
        lines.append(f"| {name} | " + " | ".join(summary(st[k]) for k, _, _ in HUMAN_STATS) + " |")
    for name, st in sims.items():
        lines.append(f"| SFFM {name} | " + " | ".join(summary(st[k]) for k, _, _ in HUMAN_STATS) + " |")
    lines += ["", "SocialParams fields written:", ""] + [f"- {k}: {v}" for k, v in fields.items()]
    lines += ["", "Reasons:", ""] + [f"- {n}" for n in notes]
    return "\n".join(lines) + "\n"
