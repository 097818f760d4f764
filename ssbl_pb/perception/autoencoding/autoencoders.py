"""Autoencoders that compress Pepper's camera image into a state (paper III-B): ``conv`` and ``saev``.

Both share the encoder trunk C3∘C2∘C1 (conv → ELU → BatchNorm → dropout; C3 without activation). Facts from the
original code (shared/reference/peppersocial.md, "Autoencoders"):

* ``saev`` (eqs. 3-7): S = spatial softmax of ``alpha * C3`` per channel (``alpha`` trainable, initial 1.0),
  the expected (x, y) on a [-1, 1] grid and the presence ``rho = sum P * g`` with g a Gaussian of sigma 0.088
  around (x, y). Decoder B∘C6∘C5∘C4∘Δ: Δ draws ELU(rho - distance to (x, y)) per keypoint, two ELU convs
  ('same'), a 3-channel conv with tanh (the code's choice; the paper says sigmoid), plus a trainable image B.
* ``conv``: the trunk, ELU, Dense (512, ELU); decoder Dense → a 16-channel grid → conv → 3-channel conv (tanh).

Departures (docs/decisions.md, "Camera state representations"): ``g`` peaks at 1 instead of summing to 1, so a
one-hot map has presence 1 and a uniform one about ``2 pi sigma^2 / 4`` (the paper's "near 1 / near 0"; the
code's normalisation caps presence at 1/sum(g) ≈ 0.012 on the 82x82 grid and makes it depend on the grid);
the reconstruction is at ``recon_size`` (the code's ``down_factor``); and sizes are a config (``SIZES``).

Keypoint coordinates: x is the column (right), y the row (down), both -1 at the first C3 pixel centre and +1
at the last; ``keypoint_pixels`` maps them to input-image pixels (C3 sees only the image's centre).
"""

from __future__ import annotations

import dataclasses

import torch
from torch import nn
from torch.nn import functional as F

from ...errors import UserError

ARCHS = ("conv", "saev")
SIGMA = 0.088  # presence Gaussian, [-1, 1] units: the code's exp(-(8 d)^2), sigma = 1 / (8 sqrt 2)


@dataclasses.dataclass(frozen=True)
class AESize:
    """Layer sizes of both autoencoders (the trunk is shared)."""

    name: str
    input_size: int  # square RGB input, pixels
    channels: tuple[int, int, int]  # C1, C2, C3 (C3 = number of keypoints)
    kernels: tuple[int, int, int]
    stride1: int  # C1's stride (C2, C3 use 1)
    recon_size: int  # the decoder's output resolution (input downsampled to it for the loss)
    decoder_channels: tuple[int, int]  # SAEV's C4, C5; the conv AE uses C5's
    dense: int  # conv AE bottleneck
    dense_grid: int  # conv AE: the Dense layer's output grid (16 channels), upsampled to ``recon_size``
    dropout: float = 0.2

    @property
    def keypoints(self) -> int:
        return self.channels[2]

    @property
    def feature_grid(self) -> int:
        """Side of the C3 map (valid padding)."""
        k1, k2, k3 = self.kernels
        return (self.input_size - k1) // self.stride1 + 1 - (k2 - 1) - (k3 - 1)


SIZES = {
    # the original's numbers: 96x96 input, C3 82x82, reconstruction at 96x96, conv AE Dense 512 -> 96x96x16
    "paper": AESize("paper", 96, (64, 32, 16), (7, 5, 5), 1, 96, (16, 32), 512, 96),
    # sized for 2 CPU cores (docs/decisions.md): 64x64 input, strided 5x5 C1, C3 26x26, reconstruction 32x32
    "cpu": AESize("cpu", 64, (16, 32, 16), (5, 3, 3), 2, 32, (16, 16), 256, 16),
}
DEFAULT_SIZE = "cpu"


def get_size(name: str) -> AESize:
    if name not in SIZES:
        raise UserError(f"autoencoder size {name!r}: expected one of {sorted(SIZES)}")
    return SIZES[name]


# -- the spatial operations (S and Δ) ------------------------------------------------------------------------
def grid_coords(n: int, device: torch.device | None = None) -> torch.Tensor:
    """Pixel centres of an ``n``-pixel axis on [-1, 1] (the code's ``space_blocks``)."""
    return torch.linspace(-1.0, 1.0, n, device=device)


def spatial_softmax(z: torch.Tensor, alpha: torch.Tensor | float = 1.0) -> torch.Tensor:
    """Softmax of ``alpha * z`` over each channel's pixels: (B, K, H, W) -> probabilities of the same shape."""
    b, k, h, w = z.shape
    return F.softmax((alpha * z).reshape(b, k, h * w), dim=-1).reshape(b, k, h, w)


def spatial_expectation(p: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Expected column x and row y (each (B, K), on [-1, 1]) of per-channel distributions (B, K, H, W)."""
    _, _, h, w = p.shape
    x = (p.sum(dim=2) * grid_coords(w, p.device)).sum(dim=-1)
    y = (p.sum(dim=3) * grid_coords(h, p.device)).sum(dim=-1)
    return x, y


def distance_maps(x: torch.Tensor, y: torch.Tensor, h: int, w: int) -> torch.Tensor:
    """Distance (B, K, h, w) of every grid pixel centre to (x, y) (each (B, K)), [-1, 1] units."""
    gx, gy = grid_coords(w, x.device), grid_coords(h, x.device)
    dx2 = (gx[None, None, None, :] - x[..., None, None]) ** 2
    dy2 = (gy[None, None, :, None] - y[..., None, None]) ** 2
    return torch.sqrt(dx2 + dy2 + 1e-6)  # the code's 1e-6 keeps the gradient finite at the centre


def presence(p: torch.Tensor, x: torch.Tensor, y: torch.Tensor, sigma: float = SIGMA) -> torch.Tensor:
    """``rho = sum_ij P(i, j) g(i, j)`` with ``g`` a Gaussian of ``sigma`` around (x, y), peak 1: (B, K)."""
    _, _, h, w = p.shape
    g = torch.exp(-distance_maps(x, y, h, w) ** 2 / (2.0 * sigma ** 2))
    return (p * g).sum(dim=(2, 3))


def delta_maps(kp: torch.Tensor, h: int, w: int) -> torch.Tensor:
    """Δ (eq. 9): keypoints (B, K, 3) as (x, y, rho) -> maps ELU(rho - distance to (x, y)), (B, K, h, w)."""
    x, y, rho = kp.unbind(dim=-1)
    return F.elu(rho[..., None, None] - distance_maps(x, y, h, w))


# -- the networks -------------------------------------------------------------------------------------------
def _block(cin: int, cout: int, k: int, stride: int, dropout: float, act: bool, padding: str | int = 0
           ) -> nn.Sequential:
    layers: list[nn.Module] = [nn.Conv2d(cin, cout, k, stride=stride, padding=padding)]
    if act:
        layers.append(nn.ELU())
    layers += [nn.BatchNorm2d(cout), nn.Dropout(dropout)]
    return nn.Sequential(*layers)


class Trunk(nn.Module):
    """C3∘C2∘C1: RGB (B, 3, S, S) in [0, 1] -> feature maps (B, K, G, G), G = ``size.feature_grid``."""

    def __init__(self, size: AESize) -> None:
        super().__init__()
        (c1, c2, c3), (k1, k2, k3), d = size.channels, size.kernels, size.dropout
        self.layers = nn.Sequential(_block(3, c1, k1, size.stride1, d, True), _block(c1, c2, k2, 1, d, True),
                                    _block(c2, c3, k3, 1, d, False))

    def forward(self, img: torch.Tensor) -> torch.Tensor:
        return self.layers(img)


class Autoencoder(nn.Module):
    """Common interface: ``encode(img) -> features (B, F)`` (the RL state), ``forward(img) -> (recon, code)``."""

    arch = ""

    def __init__(self, size: AESize) -> None:
        super().__init__()
        self.size = size
        self.trunk = Trunk(size)

    @property
    def feature_dim(self) -> int:  # pragma: no cover - interface
        raise NotImplementedError

    def code(self, img: torch.Tensor) -> torch.Tensor:  # pragma: no cover - interface
        raise NotImplementedError

    def decode(self, code: torch.Tensor) -> torch.Tensor:  # pragma: no cover - interface
        raise NotImplementedError

    def encode(self, img: torch.Tensor) -> torch.Tensor:
        """The flat feature vector (B, ``feature_dim``) given to the policy."""
        return self.code(img).flatten(1)

    def forward(self, img: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        code = self.code(img)
        return self.decode(code), code


class SAEV(Autoencoder):
    """Spatial autoencoder variant: code = (B, K, 3) keypoints (x, y, presence)."""

    arch = "saev"

    def __init__(self, size: AESize) -> None:
        super().__init__(size)
        self.alpha = nn.Parameter(torch.tensor(1.0))  # inverse temperature of S (code: initial 1.0)
        c4, c5 = size.decoder_channels
        k, d = size.keypoints, size.dropout
        self.decoder = nn.Sequential(nn.Dropout(d), _block(k, c4, 5, 1, d, True, "same"),
                                     _block(c4, c5, 5, 1, d, True, "same"),
                                     nn.Conv2d(c5, 3, 7, padding="same"), nn.Tanh())
        self.bias_image = nn.Parameter(torch.zeros(1, 3, size.recon_size, size.recon_size))  # B, trainable

    @property
    def feature_dim(self) -> int:
        return 3 * self.size.keypoints

    def code(self, img: torch.Tensor) -> torch.Tensor:
        p = spatial_softmax(self.trunk(img), self.alpha)
        x, y = spatial_expectation(p)
        return torch.stack([x, y, presence(p, x, y)], dim=-1)

    def decode(self, code: torch.Tensor) -> torch.Tensor:
        r = self.size.recon_size
        return self.decoder(delta_maps(code, r, r)) + self.bias_image


class ConvAE(Autoencoder):
    """Convolutional autoencoder with a dense bottleneck: code = (B, ``size.dense``)."""

    arch = "conv"

    def __init__(self, size: AESize) -> None:
        super().__init__(size)
        g, k, d = size.feature_grid, size.keypoints, size.dropout
        self.bottleneck = nn.Sequential(nn.ELU(), nn.Flatten(), nn.Linear(k * g * g, size.dense), nn.ELU())
        self.expand = nn.Linear(size.dense, 16 * size.dense_grid ** 2)
        c5 = size.decoder_channels[1]
        self.decoder = nn.Sequential(_block(16, c5, 5, 1, d, True, "same"), nn.Conv2d(c5, 3, 7, padding="same"),
                                     nn.Tanh())

    @property
    def feature_dim(self) -> int:
        return self.size.dense

    def code(self, img: torch.Tensor) -> torch.Tensor:
        return self.bottleneck(self.trunk(img))

    def decode(self, code: torch.Tensor) -> torch.Tensor:
        g, r = self.size.dense_grid, self.size.recon_size
        grid = self.expand(code).reshape(-1, 16, g, g)
        if g != r:
            grid = F.interpolate(grid, size=(r, r), mode="bilinear", align_corners=False)
        return self.decoder(grid)


def build(arch: str, size: str | AESize = DEFAULT_SIZE) -> Autoencoder:
    """A fresh autoencoder of architecture ``arch`` (``conv`` | ``saev``) and ``size`` (a name of ``SIZES``)."""
    s = size if isinstance(size, AESize) else get_size(size)
    if arch == "saev":
        return SAEV(s)
    if arch == "conv":
        return ConvAE(s)
    raise UserError(f"--arch {arch!r}: expected one of {list(ARCHS)}")


def keypoint_pixels(xy: torch.Tensor, size: AESize) -> torch.Tensor:
    """SAEV (x, y) in [-1, 1] (..., 2) -> input-image pixel (u, v) (..., 2), pixel centres at integers.

    C3 pixel m sits at C2 pixel m + (k3 - 1)/2, C1 pixel m + (k2 - 1)/2 + (k3 - 1)/2, input pixel
    ``stride1 * that + (k1 - 1)/2``."""
    k1, k2, k3 = size.kernels
    g = size.feature_grid
    m = (xy + 1.0) * (g - 1) / 2.0  # C3 pixel index
    return size.stride1 * (m + (k2 - 1) / 2.0 + (k3 - 1) / 2.0) + (k1 - 1) / 2.0


def to_input(frames: torch.Tensor) -> torch.Tensor:
    """uint8 frames (B, H, W, 3) -> float (B, 3, H, W) in [0, 1]."""
    return frames.permute(0, 3, 1, 2).float().div_(255.0)


def downsample(img: torch.Tensor, r: int) -> torch.Tensor:
    """The reconstruction target: ``img`` (B, 3, S, S) area-averaged to ``r`` x ``r``."""
    return img if img.shape[-1] == r else F.adaptive_avg_pool2d(img, r)

