"""Autoencoders (perception/autoencoding/autoencoders.py, ae_losses.py): the spatial operations against hand
computations, gradients through every trainable part, sizes and keypoint-to-pixel geometry."""

from __future__ import annotations

import math

import pytest
import torch

from ssbl_pb.errors import UserError
from ssbl_pb.perception.autoencoding import autoencoders as A
from ssbl_pb.perception.autoencoding.ae_losses import smoothness, triplet_loss

TINY = A.AESize("tiny", 24, (4, 6, 5), (3, 3, 3), 2, 12, (4, 4), 8, 6)


def test_soft_argmax_of_a_one_hot_map_is_that_pixel() -> None:
    z = torch.zeros(1, 2, 9, 13)
    z[0, 0, 2, 10] = 60.0  # row 2, column 10
    z[0, 1, 8, 0] = 60.0
    x, y = A.spatial_expectation(A.spatial_softmax(z, 1.0))
    grid_x, grid_y = torch.linspace(-1, 1, 13), torch.linspace(-1, 1, 9)
    assert x[0].tolist() == pytest.approx([grid_x[10].item(), -1.0], abs=1e-5)
    assert y[0].tolist() == pytest.approx([grid_y[2].item(), 1.0], abs=1e-5)


def test_inverse_temperature_sharpens_the_softmax() -> None:
    z = torch.tensor([[[[0.0, 1.0]]]])
    p1, p3 = A.spatial_softmax(z, 1.0), A.spatial_softmax(z, 3.0)
    assert p1[0, 0, 0, 1].item() == pytest.approx(math.e / (1 + math.e))
    assert p3[0, 0, 0, 1].item() == pytest.approx(math.exp(3) / (1 + math.exp(3)))


def test_presence_is_one_for_a_peaked_map_and_near_zero_for_a_flat_one() -> None:
    n = 26
    peaked = torch.zeros(1, 1, n, n)
    peaked[0, 0, 7, 19] = 1.0
    flat = torch.full((1, 1, n, n), 1.0 / n ** 2)
    for p, expect in ((peaked, 1.0), (flat, None)):
        x, y = A.spatial_expectation(p)
        rho = A.presence(p, x, y).item()
        if expect is not None:
            assert rho == pytest.approx(1.0, abs=1e-4)  # sqrt(d^2 + 1e-6) is 1e-3 at the centre
        else:  # mean of g over the grid: sum_ij exp(-d^2 / 2 sigma^2) / n^2 around the centre
            g = torch.linspace(-1, 1, n)
            d2 = g[None, :] ** 2 + g[:, None] ** 2
            assert rho == pytest.approx(torch.exp(-d2 / (2 * A.SIGMA ** 2)).mean().item(), rel=1e-4)
            assert rho < 0.03


def test_delta_map_peaks_at_the_keypoint() -> None:
    n = 21  # grid step 0.1
    kp = torch.tensor([[[0.5, -0.3, 0.8], [-1.0, 1.0, 0.0]]])
    maps = A.delta_maps(kp, n, n)
    for k, (col, row) in enumerate(((15, 7), (0, 20))):
        flat = int(maps[0, k].argmax())
        assert divmod(flat, n) == (row, col)
        assert maps[0, k, row, col].item() == pytest.approx(kp[0, k, 2].item(), abs=2e-3)
    # ELU(rho - d): 1 unit away from the first keypoint the map is ELU(0.8 - 1) = exp(-0.2) - 1
    assert maps[0, 0, 7, 5].item() == pytest.approx(math.exp(-0.2) - 1, abs=1e-3)


@pytest.mark.parametrize("arch", A.ARCHS)
def test_gradients_reach_every_trainable_part(arch: str) -> None:
    torch.manual_seed(0)
    model = A.build(arch, TINY).train()
    frames = torch.rand(4, 3, 3, 24, 24)
    loss, parts = triplet_loss(model, frames)
    loss.backward()
    missing = [n for n, p in model.named_parameters() if p.grad is None or not torch.any(p.grad != 0)]
    assert not missing, missing
    assert set(parts) == {"reconstruction", "smoothness", "total"} | ({"presence"} if arch == "saev" else set())
    if arch == "saev":
        assert model.alpha.grad is not None and model.bias_image.grad is not None


@pytest.mark.parametrize("arch,dim", [("saev", 15), ("conv", 8)])
def test_feature_sizes(arch: str, dim: int) -> None:
    model = A.build(arch, TINY).eval()
    recon, _ = model(torch.rand(2, 3, 24, 24))
    assert recon.shape == (2, 3, 12, 12)
    assert model.encode(torch.rand(2, 3, 24, 24)).shape == (2, dim) == (2, model.feature_dim)


def test_sizes_match_the_paper_and_the_cpu_default() -> None:
    assert A.SIZES["paper"].feature_grid == 82  # the paper's "centre 82x82 pixels"
    assert A.SIZES["cpu"].feature_grid == 26  # (64 - 5) // 2 + 1 - 2 - 2
    with pytest.raises(UserError, match="expected one of"):
        A.build("vae")
    with pytest.raises(UserError, match="'huge'"):
        A.get_size("huge")


def test_keypoint_pixels_cover_the_centre_of_the_input() -> None:
    paper, cpu = A.SIZES["paper"], A.SIZES["cpu"]
    ends = torch.tensor([[-1.0, -1.0], [1.0, 1.0]])
    assert A.keypoint_pixels(ends, paper).tolist() == [[7.0, 7.0], [88.0, 88.0]]  # 3 + 2 + 2 px trimmed
    # C3 pixel 0 -> C1 pixel 2 -> input 2 * 2 + 2 = 6; C3 pixel 25 -> C1 27 -> input 56
    assert A.keypoint_pixels(ends, cpu).tolist() == [[6.0, 6.0], [56.0, 56.0]]


def test_smoothness_is_the_squared_second_difference() -> None:
    a = torch.tensor([[[0.0, 0.0, 0.9]]])
    b = torch.tensor([[[0.1, 0.2, 0.1]]])
    c = torch.tensor([[[0.3, 0.1, 0.5]]])
    # (b - a) - (c - b) = (0.1 - 0.2, 0.2 + 0.1) -> 0.01 + 0.09; presence is ignored
    assert smoothness(a, b, c).item() == pytest.approx(0.1)
    assert smoothness(a[:, 0], a[:, 0], a[:, 0]).item() == 0.0
