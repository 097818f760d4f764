"""The README's promise for every tool, checked as a user meets it: bad input -> exit 2, one line on stderr
naming the problem, no traceback, nothing left at the output path.

One row per case: (tool, argv, a fragment the message must contain). ``{out}`` in argv is a path inside a fresh
temporary folder that must not exist afterwards; ``{tmp}`` is that folder; ``{file}`` an existing regular text
file; ``{binary}`` a Latin-1 (not UTF-8) CSV.
A tool is ``tools/NAME.py`` or ``-m package.module``. New tools add their rows here.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import pytest

ROOT = Path(__file__).resolve().parents[1]


class Case(NamedTuple):
    tool: str
    argv: tuple[str, ...]
    expect: str


def C(tool: str, *argv: str, expect: str) -> Case:
    return Case(tool, argv, expect)


CASES = [
    # analysis and reporting
    C("analyze_study.py", "{tmp}/none.csv", "--out", "{out}", expect="none.csv: file not found"),
    C("analyze_study.py", "{binary}", "--out", "{out}", expect="not UTF-8 text"),
    C("analyze_study.py", "{file}", "--out", "{out}", expect="missing column(s)"),
    C("analyze_study.py", "docs/examples/ratings_example.csv", "--out", "{file}/study", expect="is a file"),
    C("bench.py", "--steps", "0", "--out", "{out}.json", expect="argument --steps"),
    C("bench.py", "--out", "{file}/bench.json", expect="is a file"),
    C("bench_policies.py", "--policies", "nosuch", "--out", "{out}", expect="--policies 'nosuch'"),
    C("bench_policies.py", "--scenarios", "bogus", "--out", "{out}", expect="scenario 'bogus'"),
    C("bench_policies.py", "--episodes", "0", "--out", "{out}", expect="argument --episodes"),
    C("bench_training.py", "--set", "n_envz=3", "--out", "{out}.json", expect="n_envz"),
    C("bench_training.py", "--steps", "0", "--out", "{out}.json", expect="argument --steps"),
    C("compare.py", "--pairs", "-2", "--out", "{out}", expect="argument --pairs"),
    C("compare.py", "--baseline", "nosuch", "--out", "{out}", expect="--baseline 'nosuch'"),
    C("compare.py", "--episodes", "1", "--out", "{out}", expect="argument --episodes"),
    C("compare.py", "--scenario", "bogus", "--episodes", "4", "--out", "{out}", expect="scenario 'bogus'"),
    C("demo.py", "--width", "0", "--out", "{out}", expect="argument --width"),
    C("demo.py", "--width", "100000", "--out", "{out}", expect="argument --width"),
    C("demo.py", "--policy", "nosuch", "--out", "{out}", expect="--policy 'nosuch'"),
    C("demo.py", "--out", "{file}/demo", expect="is a file"),
    C("evaluate.py", "--policy", "nosuch", "--out", "{out}", expect="--policy 'nosuch'"),
    C("evaluate.py", "--policy", "sffm", "--scenario", "bogus", "--out", "{out}", expect="scenario 'bogus'"),
    C("evaluate.py", "--policy", "sffm", "--episodes", "0", "--out", "{out}", expect="argument --episodes"),
    C("evaluate.py", "--policy", "sffm", "--paths", "-1", "--out", "{out}", expect="argument --paths"),
    C("evaluate.py", "--policy", "sffm", "--workers", "-3", "--out", "{out}", expect="argument --workers"),
    C("evaluate.py", "--policy", "sffm", "--out", "{file}/eval", expect="is a file"),
    C("evaluate.py", "--policy", "sffm", "--robot-yaml", "{tmp}/none.yaml", "--out", "{out}", expect="none.yaml"),
    C("evaluate.py", "--policy", "sffm", "--room-yaml", "{file}", "--out", "{out}", expect="a_file.txt"),
    C("evaluate.py", "--policy", "{file}", "--out", "{out}", expect="--policy"),
    C("evaluate.py", "--policy", "vector", "--obs-mode", "camera", "--episodes", "2", "--out", "{out}",
      expect="obs_mode"),
    C("main_job.py", "--steps", "10", "--out", "{out}", expect="argument --steps"),
    C("main_job.py", "--out", "{file}/quick", expect="is a file"),
    C("render_episode.py", "--policy", "sffm", "--width", "0", "--out", "{out}/x.mp4", expect="argument --width"),
    C("render_episode.py", "--policy", "sffm", "--width", "-10", "--out", "{out}/x.mp4", expect="argument --width"),
    C("render_episode.py", "--policy", "sffm", "--width", "100000", "--out", "{out}/x.mp4", expect="argument --width"),
    C("render_episode.py", "--policy", "sffm", "--out", "{out}/x.avi", expect="expected a .mp4"),
    C("render_episode.py", "--policy", "nosuch", "--out", "{out}/x.mp4", expect="--policy 'nosuch'"),
    C("render_episode.py", "--policy", "sffm", "--scenario", "bogus", "--out", "{out}/x.mp4",
      expect="scenario 'bogus'"),
    C("ship_policy.py", "{tmp}/none", expect="not a training run directory"),
    C("ship_policy.py", "{tmp}", "--episodes", "0", expect="argument --episodes"),
    C("ship_policy.py", "{tmp}", "--name", "../evil", expect="--name '../evil'"),
    # training
    C("train_pb.py", "--scenario", "bogus", "--out", "{out}", expect="scenario 'bogus'"),
    C("train_pb.py", "--set", "env.bogus=1", "--out", "{out}", expect="config.env"),
    C("train_pb.py", "--set", "ppo.bogus=1", "--out", "{out}", expect="bogus"),
    C("train_pb.py", "--set", "reward.w_smooth=0.3", "--out", "{out}", expect="reward_ramp.w_smooth"),
    C("train_pb.py", "--set", "env.world.room_size=[1,1]", "--out", "{out}", expect="world.room_size"),
    C("train_pb.py", "--set", "env.world.n_humans=4", "--out", "{out}", expect="world.n_humans"),
    C("train_pb.py", "--set", "env.robot.max_speed=-1", "--out", "{out}", expect="max_speed"),
    C("train_pb.py", "--set", "noequals", "--out", "{out}", expect="--set 'noequals'"),
    C("train_pb.py", "--init-from", "{tmp}/none", "--out", "{out}", expect="--init-from"),
    C("train_pb.py", "--out", "{file}/run", expect="is a file"),
    C("train_pb.py", "--resume", "{tmp}/none", expect="not a run directory"),
    C("train_pb.py", "--config", "{tmp}/none.yaml", "--out", "{out}", expect="none.yaml: file not found"),
    C("train_pb.py", "--total-steps", "0", "--out", "{out}", expect="argument --total-steps: 0: expected"),
    C("train_pb.py", "--set", "feature_smoothing=0.5", "--out", "{out}",
      expect="feature_smoothing = 0.5: expected 1 for encoder 'none'"),
    # tracking
    C("trace_episode.py", "--policy", "nosuch", "--out", "{out}", expect="--policy 'nosuch'"),
    C("trace_episode.py", "--policy", "sffm", "--perception", "movenet", "--oracle", "members,places", "--out",
      "{out}", expect="'places' is not one of"),
    C("trace_episode.py", "--policy", "sffm", "--oracle", "members", "--out", "{out}",
      expect="--oracle needs --perception"),
    C("trace_episode.py", "--policy", "sffm", "--scenario", "bogus", "--out", "{out}", expect="scenario 'bogus'"),
    C("track.py", "{tmp}/none.avi", "--calib", "{tmp}/none.xml", "--out", "{out}", expect="none"),
    C("track.py", "{file}", "--calib", "{tmp}/none.xml", "--out", "{file}/tracks", expect="is a file"),
    C("eval_tracking.py", "--tracks", "{tmp}/none", "--gt", "{tmp}/none.xml", "--json", "{out}.json",
      expect="none"),
    C("eval_tracking.py", "--tracks", "{tmp}", "--gt", "{tmp}/gt.xml", "--range", "5:2", expect="--range"),
    C("bench_tracking.py", "--data", "{tmp}/none", "--out", "{out}", "--doc", "{out}.md", expect="none"),
    C("bench_pets_facing.py", "--data", "{tmp}/none", "--out", "{out}", expect="vtest.avi: not found"),
    C("bench_pets_facing.py", "--start", "5", "--stop", "2", "--out", "{out}", expect="--start 5 --stop 2"),
    C("detector_coverage.py", "--video", "{tmp}/none.avi", "--out", "{out}", expect="none.avi: not found"),
    C("detector_coverage.py", "--range", "5:2", "--out", "{out}", expect="--range"),
    C("detector_coverage.py", "--out", "{file}/cov", expect="a_file.txt is a file, not a directory"),
    # calibration
    C("calibrate_camera.py", "{tmp}/none.jpg", "--out", "{out}.yaml", expect="none.jpg"),
    C("calibrate_camera.py", "{file}", "--board", "9y6", "--out", "{out}.yaml", expect="board '9y6'"),
    C("calibrate_humans.py", "--data", "{tmp}/none", "--out", "{out}.yaml", expect="data folder not found"),
    C("calibrate_humans.py", "--episodes", "0", "--out", "{out}.yaml", expect="argument --episodes"),
    C("camera_pose.py", "{tmp}/none.png", "--camera", "{tmp}/none.yaml", "--square", "0.025", "--out",
      "{out}.yaml", expect="none"),
    C("fit_room_pointcloud.py", "{tmp}/none.pcd", "--out", "{out}.yaml", expect="none.pcd"),
    C("fit_room_pointcloud.py", "{file}", "--up", "w", "--out", "{out}.yaml", expect="up axis 'w'"),
    C("identify_dynamics.py", "{tmp}/none.csv", "--out", "{out}.yaml", expect="none.csv"),
    C("identify_dynamics.py", "{file}", "--out", "{out}.yaml", expect="a_file.txt"),
    C("import_map.py", "{tmp}/none.yaml", "--seed", "0", "0", "--out", "{out}.yaml", expect="none.yaml"),
    C("import_map.py", "{file}", "--seed", "0", "0", "--out", "{out}.yaml", expect="a_file.txt"),
    C("import_map.py", "{file}", "--out", "{out}.yaml", expect="give --region and/or --seed"),
    C("import_map.py", "{file}", "--seed", "0", "0", "--out", "{file}/room.yaml", expect="is a file"),
    # camera state representations: frames, autoencoders
    C("collect_frames.py", "--episodes", "1", "--out", "{out}", expect="expected a .npz file name"),
    C("collect_frames.py", "--episodes", "1", "--size", "5", "--out", "{out}.npz", expect="--size 5"),
    C("collect_frames.py", "--episodes", "0", "--out", "{out}.npz", expect="--episodes 0"),
    C("collect_frames.py", "--episodes", "1", "--camera-hfov", "200", "--out", "{out}.npz",
      expect="--camera-hfov 200: expected 5..120 degrees"),
    C("collect_frames.py", "--episodes", "1", "--policies", "nosuch", "--out", "{out}.npz", expect="'nosuch'"),
    C("collect_frames.py", "--episodes", "1", "--scenario", "nosuch", "--out", "{out}.npz", expect="nosuch"),
    C("train_ae.py", "--frames", "{file}", "--arch", "vae", "--out", "{out}", expect="--arch 'vae'"),
    C("train_ae.py", "--frames", "{file}", "--arch", "saev", "--size", "huge", "--out", "{out}", expect="'huge'"),
    C("train_ae.py", "--frames", "{file}", "--arch", "saev", "--out", "{out}",
      expect="a_file.txt: not a frames file written by tools/collect_frames.py"),
    C("train_ae.py", "--frames", "{tmp}/none.npz", "--arch", "conv", "--out", "{out}", expect="file not found"),
    C("train_ae.py", "--frames", "{file}", "--arch", "saev", "--steps", "0", "--out", "{out}", expect="--steps 0"),
    C("train_ae.py", "--frames", "{file}", "--arch", "saev", "--smoothness-weight", "-1", "--out", "{out}",
      expect="--smoothness-weight -1.0: expected a finite number >= 0"),
    C("train_ae.py", "--frames", "{file}", "--arch", "saev", "--resume", "{tmp}/nosuch.pt", "--out", "{out}",
      expect="nosuch.pt: file not found"),
    C("train_ae.py", "--frames", "{file}", "--arch", "saev", "--snapshot-every", "300", "--out", "{out}",
      expect="--snapshot-every 300: expected 0 or a multiple of the evaluation interval 250"),
    # groups calibration
    C("calibrate_groups.py", "{tmp}/nosuch", "--out", "{out}.yaml", expect="nosuch: not found"),
    C("calibrate_groups.py", "{tmp}", "--out", "{out}.yaml", expect="no features.mat at or below"),
    C("calibrate_groups.py", "{file}", "--out", "{out}.yaml",
      expect="a_file.txt: a file; expected a dataset folder holding features.mat and groundtruth.mat"),
    C("calibrate_groups.py", "--out", "{out}", expect="expected a .yaml file name"),
    C("calibrate_groups.py", "--per-size", "0", "--out", "{out}.yaml", expect="--per-size 0"),
    # deploy: nothing connects or moves before the inputs are checked
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--port", "1", "--policy", "sffm", "--log-dir", "{out}",
      expect="cannot connect to tcp://127.0.0.1:1"),
    C("-m ssbl_pb.deploy", "--robot-ip", "10.255.255.1", "--policy", "sffm", "--log-dir", "{out}",
      expect="cannot connect"),
    C("-m ssbl_pb.deploy", "--log-dir", "{out}", expect="give --robot-ip"),
    C("-m ssbl_pb.deploy", "--url", "http://pepper:80", "--log-dir", "{out}", expect="--url 'http://pepper:80'"),
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--max-speed", "0.8", "--log-dir", "{out}",
      expect="--max-speed 0.8"),
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--policy", "nosuch", "--log-dir", "{out}", expect="nosuch"),
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--detector", "yolo", "--log-dir", "{out}",
      expect="--detector 'yolo'"),
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--map", "{file}", "--start-pose", "0", "0", "0",
      "--log-dir", "{out}", expect="--map"),
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--start-pose", "0", "0", "0", "--log-dir", "{out}",
      expect="--start-pose is a pose on a map"),
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--log-dir", "{file}", expect="exists and is not a directory"),
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--groups", "round", "--log-dir", "{out}",
      expect="argument --groups"),
    C("-m ssbl_pb.virtual.pepper", "--groups", "round", expect="argument --groups"),
    C("-m ssbl_pb.virtual.pepper", "--listen", "tcp://0.0.0.0:0", "--log", "{out}",
      expect="not a loopback address"),
    C("-m ssbl_pb.virtual.pepper", "--listen", "127.0.0.1:9559", expect="--listen '127.0.0.1:9559'"),
    C("-m ssbl_pb.virtual.pepper", "--listen", "tcp://127.0.0.1:0", "--scenario", "nosuch", "--log", "{out}",
      expect="scenario 'nosuch'"),
    C("-m ssbl_pb.deploy.watchdog", "--robot", "tcp://127.0.0.1:1", expect="cannot reach ALMotion"),
    C("-m ssbl_pb.deploy.watchdog", "--limit", "0", expect="--limit 0"),
    C("-m ssbl_pb.deploy.plot", "{tmp}", expect="no log.jsonl"),
    C("bench_deploy.py", "--faults", "meteor", "--out", "{out}", expect="--faults meteor"),
    C("bench_deploy.py", "--runs", "-1", "--out", "{out}", expect="argument --runs"),
    C("bench_deploy.py", "--walker-runs", "0", "--out", "{out}", expect="argument --walker-runs"),
    C("bench_deploy.py", "--policy", "nosuch", "--out", "{out}", expect="--policy 'nosuch'"),
    C("bench_deploy.py", "--groups", "round", "--out", "{out}", expect="argument --groups"),
    # the observation model
    C("bench_policies.py", "--perception", "maybe", "--out", "{out}", expect="--perception maybe"),
    C("bench_facing.py", "--frames", "0", "--out", "{out}", expect="argument --frames"),
    C("bench_facing.py", "--out", "{file}/facing", expect="is a file"),
    # the person bodies: the tool that makes them, MoveNet's recall on them, the switch in the tools that show them
    C("make_bodies.py", "--out", "{file}/bodies", expect="is a file"),
    C("bench_bodies.py", "--groups", "-1", "--out", "{out}", expect="argument --groups"),
    C("bench_bodies.py", "--out", "{file}/bodies", expect="is a file"),
    # the observation model measured from deploy runs
    C("fit_observation.py", "{tmp}", "--out", "{out}", expect="expected a run folder"),
    C("fit_observation.py", "{tmp}", "--detector", "hog", "--out", "{out}", expect="argument --detector"),
    C("demo.py", "--appearance", "mesh", "--out", "{out}", expect="argument --appearance"),
    C("render_episode.py", "--policy", "sffm", "--appearance", "mesh", "--out", "{out}/x.mp4",
      expect="argument --appearance"),
    C("-m ssbl_pb.virtual.pepper", "--appearance", "mesh", "--log", "{out}", expect="argument --appearance"),
    C("bench_deploy.py", "--appearance", "mesh", "--out", "{out}", expect="argument --appearance"),
    C("evaluate.py", "--policy", "sffm", "--perception", "maybe", "--out", "{out}", expect="argument --perception"),
    C("train_pb.py", "--set", "env.perception.miss_prob=2", "--out", "{out}", expect="perception.miss_prob"),
    # a calibration file's own checks name the file
    C("train_pb.py", "--config", "tests/config_specs/small_room.yaml", "--out", "{out}",
      expect="small_room.yaml: world.room_size = (1, 1)"),
    C("train_pb.py", "--config", "tests/config_specs/bad_lr.yaml", "--out", "{out}",
      expect="bad_lr.yaml: ppo.learning_rate = -1"),
    C("train_pb.py", "--config", "tests/config_specs/perception_word.yaml", "--out", "{out}",
      expect="perception_word.yaml: env.perception = 'on': expected false, true, one of ['movenet', 'colour'] or a "
             "mapping of ['detector'"),
    C("evaluate.py", "--policy", "sffm", "--camera-yaml", "tests/camera_specs/negative_height.yaml", "--out", "{out}",
      expect="negative_height.yaml: camera pepper_camera_top: camera_height=-1.15 must be > 0"),
    C("evaluate.py", "--policy", "sffm", "--room-yaml", "tests/room_specs/tiny.yaml", "--out", "{out}",
      expect="tiny.yaml: world.room_size = (3.0, 3.0): expected each side >= 6.26 m"),
    # deploy, the virtual Pepper, the watchdog, the deploy benchmark
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--map", "{file}", "--start-pose", "nan", "20", "0",
      "--log-dir", "{out}", expect="--start-pose nan 20 0: expected three finite numbers"),
    C("-m ssbl_pb.deploy", "--robot-ip", "127.0.0.1", "--rate", "20", "--log-dir", "{out}",
      expect="--rate 20: the policy 'vector' was trained at 10 Hz"),
    C("-m ssbl_pb.virtual.pepper", "--seed", "-1", "--log", "{out}", expect="argument --seed"),
    C("-m ssbl_pb.virtual.pepper", "--security-distance", "-1", "--log", "{out}",
      expect="argument --security-distance"),
    C("-m ssbl_pb.virtual.pepper", "--duration", "-5", "--log", "{out}", expect="argument --duration"),
    C("-m ssbl_pb.virtual.pepper", "--hang-stops", "-1", "--log", "{out}", expect="argument --hang-stops"),
    C("-m ssbl_pb.deploy.watchdog", "--limit", "soon", expect="argument --limit"),
    C("bench_deploy.py", "--scenario", "bogus", "--out", "{out}", expect="scenario 'bogus'"),
    C("bench_deploy.py", "--soak", "nan", "--out", "{out}", expect="argument --soak"),
    C("bench_deploy.py", "--seed", "-1", "--out", "{out}", expect="argument --seed: -1: expected an integer >= 0"),
    C("bench_deploy.py", "--seed", "-1", "--lockstep", "--out", "{out}", expect="argument --seed"),
    C("bench_deploy.py", "--runs", "0", "--faults", "none", "--soak", "0", "--out", "{tmp}",
      expect="holds files this tool did not write"),
    C("table1.py", "--budget", "huge", "--out", "{out}", expect="--budget 'huge'"),
    C("table1.py", "--budget", "smoke", "--seeds", "0", "--out", "{out}", expect="--seeds 0"),
    C("table1.py", "--budget", "smoke", "--camera-hfov", "0", "--out", "{out}", expect="--camera-hfov 0: expected"),
    C("table1.py", "--budget", "smoke", "--feature-smoothing", "0", "--out", "{out}",
      expect="--feature-smoothing 0.0: expected a number in (0, 1]"),
    C("table1.py", "--budget", "smoke", "--rows", "nosuch", "--out", "{out}", expect="row 'nosuch'"),
    C("table1.py", "--budget", "smoke", "--saev", "{file}", "--out", "{out}",
      expect="a_file.txt: unreadable, not a torch file (expected an autoencoder checkpoint of tools/train_ae.py)"),
    C("table1.py", "--budget", "smoke", "--out", "{file}", expect="not a directory"),
    C("table1.py", "--budget", "smoke", "--out", "{out}", "--storage", "{out}", expect="only with --address"),
    C("table1.py", "--budget", "smoke", "--out", "{out}", "--workers", "0", expect="--workers"),
    C("bench_camera.py", "--only", "nosuch", "--out", "{out}.json", expect="unknown part(s) ['nosuch']"),
    C("bench_camera.py", "--only", "probe", "--out", "{out}.json", expect="--only probe needs --frames"),
    C("bench_camera.py", "--only", "jitter", "--out", "{out}.json", expect="--only jitter needs --frames"),
    C("train_pb.py", "--obs-mode", "camera", "--encoder", "conv", "--set", "encoder_checkpoint={file}",
      "--out", "{out}", expect="encoder checkpoint"),
    # sweeps: bad specs, no cluster at the address, storage that cannot be written
    C("sweep.py", "{tmp}/none.yaml", "--out", "{out}", expect="none.yaml: file not found"),
    C("sweep.py", "tests/sweep_specs/unknown_key.yaml", "--out", "{out}", expect="unknown key(s) ['grids']"),
    C("sweep.py", "tests/sweep_specs/bad_override.yaml", "--out", "{out}", expect="grid key 'reward.w_bogus'"),
    C("sweep.py", "tests/sweep_specs/no_seeds.yaml", "--out", "{out}", expect="seeds: missing"),
    C("sweep.py", "tests/sweep_specs/tiny.yaml", "--out", "{out}", "--address", "127.0.0.1:1",
      expect="--address 127.0.0.1:1"),
    C("sweep.py", "tests/sweep_specs/tiny.yaml", "--out", "{out}", "--address", "127.0.0.1:1", "--storage",
      "{file}/store", expect="--storage"),
    C("sweep.py", "tests/sweep_specs/tiny.yaml", "--out", "{out}", "--storage", "{tmp}/store",
      expect="only with --address"),
    C("sweep.py", "tests/sweep_specs/tiny.yaml", "--out", "{out}", "--workers", "0", expect="argument --workers"),
    C("sweep.py", "tests/sweep_specs/tiny.yaml", "--out", "{file}/sweep", expect="is a file"),
    C("bench_sweep.py", "--workers", "1", "--out", "{out}.json", expect="argument --workers"),
    C("bench_sweep.py", "--repeats", "0", "--out", "{out}.json", expect="argument --repeats"),
    C("bench_sweep.py", "--out", "{out}.txt", expect="expected a .json"),
    C("bench_sweep.py", "--spec", "tests/sweep_specs/no_seeds.yaml", "--out", "{out}.json", expect="seeds: missing"),
    C("bench_sweep.py", "--out", "{file}/bench.json", expect="is a file"),
    # rooms with obstacles: bad room YAMLs, maps and room names
    C("evaluate.py", "--policy", "sffm", "--room-yaml", "tests/room_specs/no_place.yaml", "--episodes", "2",
      "--out", "{out}", expect="no_place.yaml: no place for a group of 2"),
    C("evaluate.py", "--policy", "sffm", "--room-yaml", "tests/room_specs/bad_box.yaml", "--out", "{out}",
      expect="bad_box.yaml: obstacles.boxes[0]"),
    C("evaluate.py", "--policy", "sffm", "--scenario", "default@map", "--out", "{out}",
      expect="room 'map' needs a room YAML with obstacles"),
    C("evaluate.py", "--policy", "sffm", "--scenario", "mixed@attic", "--out", "{out}", expect="room 'attic'"),
    C("train_pb.py", "--scenario", "mixed@map", "--out", "{out}", expect="room 'map' needs a room YAML"),
    C("train_pb.py", "--set", "env.furniture.size_min=5", "--scenario", "mixed@furnished", "--out", "{out}",
      expect="furniture.size_min = 5: too small"),
    C("import_map.py", "tests/room_specs/solid.yaml", "--region", "0.1", "1.1", "1.9", "1.9", "--out", "{out}.yaml",
      expect="all its 136 cells are occupied"),
    C("import_map.py", "tests/room_specs/solid.yaml", "--region", "0.1", "0.1", "1.9", "0.9", "--out", "{out}.yaml",
      expect="holds no free cell (0 occupied, 136 unknown)"),
    # training, evaluation, autoencoder
    C("train_pb.py", "--out", "/proc/x", expect="--out /proc/x: "),
    C("train_pb.py", "--out", "{tmp}", "--overwrite", expect="holds files but no training run"),
    C("evaluate.py", "--policy", "sffm", "--episodes", "2", "--out", "/proc/x", expect="--out /proc/x: "),
    C("train_ae.py", "--frames", "{file}", "--arch", "saev", "--resume", "{file}", "--out", "{out}",
      expect="a_file.txt: unreadable"),
    # calibration, Table I, sweeps
    C("import_map.py", "{file}", "--seed", "0", "0", "--door-width", "-1", "--out", "{out}.yaml",
      expect="--door-width -1.0: expected a width in metres > 0"),
    C("table1.py", "--budget", "smoke", "--threads", "-3", "--out", "{out}", expect="argument --threads"),
    C("table1.py", "--budget", "smoke", "--saev", "ssbl_pb/policies/camera_speed_saev/encoder.pt", "--out", "{out}",
      expect="--saev ssbl_pb/policies/camera_speed_saev/encoder.pt: learned through a 56.3 deg camera"),
    C("table1.py", "--budget", "smoke", "--saev", "{tmp}/none.pt", "--out", "{out}", expect="--saev "),
    C("sweep.py", "{tmp}", "--out", "{out}", expect="is a directory, expected a YAML file"),
    # a negative seed: numpy and gymnasium refuse it deep inside, after the output folder exists
    C("evaluate.py", "--policy", "sffm", "--seed", "-1", "--out", "{out}", expect="argument --seed: -1: expected"),
    C("compare.py", "--seed", "-1", "--out", "{out}", expect="argument --seed"),
    C("render_episode.py", "--policy", "sffm", "--seed", "-1", "--out", "{out}/x.mp4", expect="argument --seed"),
    C("demo.py", "--seed", "-1", "--out", "{out}", expect="argument --seed"),
    C("collect_frames.py", "--episodes", "1", "--seed", "-1", "--out", "{out}.npz", expect="argument --seed"),
    C("bench_facing.py", "--seed", "-1", "--out", "{out}", expect="argument --seed"),
    C("bench_policies.py", "--seed", "-1", "--out", "{out}", expect="argument --seed"),
    C("bench_seeds.py", "--runs", "{tmp}", "--out", "{out}", expect="expected a recipe's output (recipe.json)"),
    C("bench_seeds.py", "--runs", "{tmp}", "--perception", "maybe", "--out", "{out}", expect="--perception maybe"),
    C("bench_seeds.py", "--runs", "{tmp}", "--episodes", "0", "--out", "{out}", expect="argument --episodes"),
    C("main_job.py", "--seed", "-1", "--out", "{out}", expect="argument --seed: -1: expected an integer in [0, "),
    C("ablate_perception.py", "--only", "model,bogus", "--out", "{out}", expect="unknown ablation(s) ['bogus']"),
    C("ablate_perception.py", "--policy", "{tmp}/nope", "--out", "{out}", expect="--policy '"),
    C("train_pb.py", "--seed", "4294967296", "--out", "{out}", expect="argument --seed"),
    C("train_pb.py", "--set", "seed=-1", "--out", "{out}", expect="config.seed = -1: expected an integer in [0, "),
    C("train_ae.py", "--frames", "{file}", "--seed", "-1", "--out", "{out}", expect="argument --seed"),
    C("identify_dynamics.py", "{file}", "--seed", "-1", "--out", "{out}.yaml", expect="argument --seed"),
    # an empty path is the current folder: a tool would write its files there
    C("evaluate.py", "--policy", "sffm", "--out", "", expect="argument --out: '': expected a path"),
    C("train_pb.py", "--out", " ", expect="argument --out: ' ': expected a path"),
    C("demo.py", "--out", "", expect="argument --out"),
    C("train_pb.py", "--resume", "ssbl_pb/policies/vector", expect="start a new run with --init-from"),
    C("train_pb.py", "--resume", "{tmp}", "--total-steps", "0", expect="argument --total-steps: 0"),
]


def _fill(arg: str, tmp: Path, out: Path, file: Path, binary: Path) -> str:
    return (arg.replace("{out}", str(out)).replace("{tmp}", str(tmp)).replace("{file}", str(file))
            .replace("{binary}", str(binary)))


def run_tool(tool: str, argv: list[str], timeout: float = 120) -> subprocess.CompletedProcess:
    """The tool as a user runs it: ``-m`` modules in a fresh interpreter (deploy leaves by ``os._exit``), the
    scripts of tools/ in this process (their ``main`` under ``cli.run``, as their last line calls it), which
    spares each case an interpreter start and the package's imports."""
    if tool.startswith("-m "):
        cmd = [sys.executable, *tool.split()]
        return subprocess.run([*cmd, *argv], capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    return run_in_process(ROOT / "tools" / tool, argv)


def run_in_process(script: Path, argv: list[str]) -> subprocess.CompletedProcess:
    """``script``'s ``main(argv)`` under ``cli.run`` here, from the repository root, with its exit code and what it
    wrote to stdout and stderr; the signal handlers ``cli.run`` installs are put back."""
    from ssbl_pb.cli import run

    spec = importlib.util.spec_from_file_location(f"_tool_{script.stem}", script)
    module = importlib.util.module_from_spec(spec)
    out, err = io.StringIO(), io.StringIO()
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    cwd, code = os.getcwd(), 0
    try:
        os.chdir(ROOT)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            spec.loader.exec_module(module)
            try:
                run(module.main, argv)
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        os.chdir(cwd)
        for s, h in handlers.items():
            signal.signal(s, h)
    return subprocess.CompletedProcess([str(script), *argv], code, out.getvalue(), err.getvalue())


@pytest.mark.parametrize("case", CASES, ids=[f"{c.tool}:{' '.join(c.argv)}"[:80] for c in CASES])
def test_bad_input_is_one_clean_line(case: Case, tmp_path: Path) -> None:
    out = tmp_path / "out" / "result"
    file = tmp_path / "a_file.txt"
    file.write_text("not a directory\n")
    binary = tmp_path / "latin1.csv"
    binary.write_bytes("participant,condition,item,rating\nJos\xe9,a,safe,5\n".encode("latin-1"))
    res = run_tool(case.tool, [_fill(a, tmp_path, out, file, binary) for a in case.argv])
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2, f"exit {res.returncode}, stderr:\n{res.stderr}"
    assert "Traceback" not in res.stderr, res.stderr
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    assert case.expect in lines[0], f"expected {case.expect!r} in {lines[0]!r}"
    assert not (tmp_path / "out").exists(), f"left behind: {sorted(p.name for p in (tmp_path / 'out').rglob('*'))}"


def test_every_tool_has_a_case() -> None:
    tools = {p.name for p in (ROOT / "tools").glob("*.py")}
    covered = {c.tool for c in CASES}
    assert tools <= covered, f"tools with no bad-input case: {sorted(tools - covered)}"
