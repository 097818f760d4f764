"""Speed benchmarks of the simulator (used by tools/bench.py): raw PyBullet limits vs the world and env."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..agents.rollout import run_episodes
from ..analysis.evaluation import Setup
from ..env.gymenv.approach import ApproachGroupEnv
from ..env.view.bullet import pybullet as p
from ..env.view.cameras import first_person_view, perspective
from ..env.view.world import World
from ..params import HumansLook, WorldParams
from ..training.vec_env import BatchedVecEnv

# five people in view of a robot at the origin facing +x: 2.2-3.8 m away within +-20 deg of bearing (inside the
# camera's +-28 deg), each facing the robot; rows x, y (m), yaw (rad)
FIVE_IN_VIEW = np.array([[r * np.cos(b), r * np.sin(b), np.pi + b]
                         for r, b in ((2.2, 0.0), (2.8, -0.30), (2.8, 0.30), (3.8, -0.15), (3.8, 0.15))])


def rate(fn: Callable[[], None], n: int, repeats: int = 5) -> float:
    """Best calls per second of ``fn`` over ``repeats`` runs of ``n`` calls."""
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = max(best, n / (time.perf_counter() - t0))
    return best


def simulator_rates(n_steps: int = 20_000, n_frames: int = 500, seed: int = 0) -> dict[str, float]:
    """raw_step_per_s, raw_render_fps_84, world_step_per_s, camera_fps_84, camera_fps_128, env_step_per_s,
    env_furnished_step_per_s (random furnished rooms), env_furnished_waypoints_step_per_s (the same with
    ``waypoints``), batched_env_step_per_s (env steps of the 8-copy training
    env, smoothing and shield included)."""
    world = World()
    world.reset(np.random.default_rng(seed))
    world.sync()
    c = world.client
    out = {"raw_step_per_s": rate(lambda: p.stepSimulation(physicsClientId=c), n_steps)}
    view = first_person_view(world.robot_pose, world.robot_params)
    proj = perspective(world.robot_params.camera_hfov_deg, 84, 84)
    out["raw_render_fps_84"] = rate(lambda: p.getCameraImage(84, 84, view, proj, shadow=0,
                                                              flags=p.ER_NO_SEGMENTATION_MASK,
                                                              renderer=p.ER_TINY_RENDERER, physicsClientId=c),
                                    n_frames)
    cmd = np.array([0.3, 0.1, 0.2])
    out["world_step_per_s"] = rate(lambda: world.step(cmd), n_steps)

    def step_and_render(size: int) -> Callable[[], None]:
        def fn() -> None:
            world.step(cmd)
            world.render_first_person(size, size)
        return fn

    world.reset(np.random.default_rng(seed))
    out["camera_fps_84"] = rate(step_and_render(84), n_frames)
    out["camera_fps_128"] = rate(step_and_render(128), n_frames)
    world.close()

    actions = np.random.default_rng(seed).uniform(-1, 1, (n_steps, 2)).astype(np.float32)
    # the empty room, a new randomly furnished room every episode (its drawing and spawning timed with the
    # steps), and the same with the way round the furniture planned each episode and looked up each step (the
    # shipped policy's); measured in turn, so that a pause of the machine does not fall on one of them only
    out.update(env_rates({"env_step_per_s": ApproachGroupEnv(),
                          "env_furnished_step_per_s": ApproachGroupEnv(scenario="default@furnished"),
                          "env_furnished_waypoints_step_per_s": ApproachGroupEnv(scenario="default@furnished",
                                                                                 waypoints=True)}, actions, seed))

    venv = BatchedVecEnv(8, smoothing=0.4, shield=True)  # as training runs it (configs/vector_ff.yaml)
    venv.seed(seed)
    venv.reset()
    batch_actions = actions[: (n_steps // 8) * 8].reshape(-1, 8, 2)
    j = [0]

    def batched_step() -> None:
        venv.step(batch_actions[j[0] % len(batch_actions)])
        j[0] += 1

    batched_step()  # compiles the kernels (or loads them from the cache) outside the timing
    out["batched_env_step_per_s"] = 8 * rate(batched_step, n_steps // 8)
    return out


def people_frame_rates(n_frames: int = 200, sizes: tuple[tuple[int, int], ...] = ((320, 240), (640, 480)),
                       repeats: int = 5) -> dict[str, float]:
    """First-person frames per second with the five members of ``FIVE_IN_VIEW`` drawn as proxies and as bodies
    (``humans.appearance``), at each of ``sizes`` (w, h): ``people5_fps_{proxy,body}_{w}`` and the frame-time
    ratio ``people5_body_vs_proxy_time_{w}``. Each frame syncs the scene (as a moving group needs) and renders."""
    out: dict[str, float] = {}
    worlds = {}
    for look in ("proxy", "body"):
        world = World(WorldParams(n_humans=5, formation="circular", humans=HumansLook(look)))
        world.reset(np.random.default_rng(0))
        world.base.pose = np.zeros(3)
        world.group.pos[:], world.group.yaw[:] = FIVE_IN_VIEW[:, :2], FIVE_IN_VIEW[:, 2]
        worlds[look] = world

    def frame(world: Any, w: int, h: int) -> Callable[[], None]:
        def fn() -> None:
            world.invalidate()
            world.render_first_person(w, h)
        return fn

    try:
        for w, h in sizes:
            for _ in range(repeats):  # in turn, so that a pause of the machine does not fall on one of them only
                for look, world in worlds.items():
                    key = f"people5_fps_{look}_{w}"
                    out[key] = max(out.get(key, 0.0), rate(frame(world, w, h), max(1, n_frames // repeats), 1))
            out[f"people5_body_vs_proxy_time_{w}"] = out[f"people5_fps_proxy_{w}"] / out[f"people5_fps_body_{w}"]
    finally:
        for world in worlds.values():
            world.close()
    return out


def env_rates(envs: dict[str, Any], actions: np.ndarray, seed: int = 0, repeats: int = 10) -> dict[str, float]:
    """Steps per second of each env in an SB3-style loop (reset when an episode ends) under ``actions``: the best of
    ``repeats`` runs of ``len(actions) // 4`` steps (~16 random-action episodes each), the envs taking turns run by
    run; closes them."""
    loops = {}
    for name, env in envs.items():
        env.reset(seed=seed)
        loops[name] = _stepper(env, actions)
        loops[name]()  # compiled kernels loaded outside the timing
    best = dict.fromkeys(envs, 0.0)
    try:
        for _ in range(repeats):
            for name, loop in loops.items():
                best[name] = max(best[name], rate(loop, len(actions) // 4, repeats=1))
    finally:
        for env in envs.values():
            env.close()
    return best


def _stepper(env: Any, actions: np.ndarray) -> Callable[[], None]:
    i = [0]

    def env_step() -> None:
        _, _, term, trunc, _ = env.step(actions[i[0] % len(actions)])
        i[0] += 1
        if term or trunc:
            env.reset()
    return env_step


def evaluation_seconds(episodes: int = 200, policy: str = "vector", seed: int = 500_000) -> dict[str, float]:
    """CPU and wall seconds to evaluate ``policy`` on ``episodes`` default-scenario episodes in one process (what
    ``tools/evaluate.py --workers 1`` spends after start-up), and its success rate (a check that it played)."""
    import torch

    torch.set_num_threads(1)
    run_episodes(Setup(policy), range(seed, seed + 2), 1)  # imports, model load, compiled kernels: not timed
    t0, c0 = time.perf_counter(), time.process_time()
    res = run_episodes(Setup(policy), range(seed, seed + episodes), 1)
    return {"evaluate_episodes": episodes, "evaluate_cpu_s": time.process_time() - c0,
            "evaluate_wall_s": time.perf_counter() - t0,
            "evaluate_success": float(np.mean([r.metrics["success"] for r in res]))}

