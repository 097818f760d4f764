"""Every shipped policy (ssbl_pb/policies/NAME/) has the config that retrains it, configs/shipped/NAME.yaml, and
the two agree on everything that defines training: the env, reward, algorithm and its hyperparameters, the
observation, the steps and the seed. Ignored, because a run records them as its own and not as a choice:
``name`` (the run's directory name), ``encoder_checkpoint`` (the run names its own copy of the encoder; unset in
configs/shipped/ means the shipped encoder) and ``normalize_obs`` unset vs null (both the automatic choice).

A chain of fine-tunes (the Vector policy's eight stages) is one documented command sequence at the top of
NAME.yaml; every stage it names must exist in configs/shipped/ and load."""

import re
from pathlib import Path

import pytest
import yaml

from ssbl_pb.policies import SHIPPED
from ssbl_pb.training.config import load_config

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_CONFIGS = ROOT / "configs" / "shipped"
IGNORED = ("name", "encoder_checkpoint")


def _training_keys(data: dict) -> dict:
    data = {k: v for k, v in data.items() if k not in IGNORED}
    if data.get("normalize_obs", "unset") is None:  # recorded as null = left unset
        data.pop("normalize_obs")
    return data


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_each_shipped_policy_is_the_one_its_config_trains(name: str) -> None:
    documented_path = SHIPPED_CONFIGS / f"{name}.yaml"
    assert documented_path.is_file(), f"shipped policy {name!r} has no {documented_path.relative_to(ROOT)}"
    documented = yaml.safe_load(documented_path.read_text())
    recorded = yaml.safe_load((SHIPPED[name] / "config.yaml").read_text())
    assert documented["name"] == name
    assert _training_keys(recorded) == _training_keys(documented)
    # and both resolve to the same training config under today's defaults
    own = {"encoder_checkpoint": str(SHIPPED[name] / recorded["encoder_checkpoint"])} if recorded.get(
        "encoder_checkpoint") else None  # relative to the policy's folder
    resolved = {k: v for k, v in vars(load_config(SHIPPED[name] / "config.yaml", own)).items() if k not in IGNORED}
    assert resolved == {k: v for k, v in vars(load_config(documented_path)).items() if k not in IGNORED}


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_the_command_sequence_names_configs_that_exist(name: str) -> None:
    header = "\n".join(line for line in (SHIPPED_CONFIGS / f"{name}.yaml").read_text().splitlines()
                       if re.match(r"#\s+python ", line))  # the sequence's commands
    named = re.findall(r"--config (\S+\.yaml)", header)
    assert f"configs/shipped/{name}.yaml" in named, "the sequence ends with the shipped policy's own config"
    for path in named:
        cfg = load_config(ROOT / path)
        assert cfg.name == Path(path).stem, f"{path}: its name decides runs/NAME, which the next stage starts from"
    for run in re.findall(r"--init-from runs/(\w+)", header):  # each stage starts from an earlier one's run
        assert f"configs/shipped/{run}.yaml" in named[:named.index(f"configs/shipped/{name}.yaml")], run


def test_every_config_loads() -> None:
    """Top-level and shipped training configs load with today's code (configs/archive/ is history, untested;
    configs/rooms/ and configs/sweeps/ are not training configs)."""
    paths = sorted((ROOT / "configs").glob("*.yaml")) + sorted(SHIPPED_CONFIGS.glob("*.yaml"))
    assert len(paths) >= 4
    for path in paths:
        assert load_config(path).name, path
