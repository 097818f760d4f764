"""Tsai camera model (R. Tsai 1987, R. Willson's reference code) as used by the PETS 2009 calibration files.

World units in the XML are millimetres; this module speaks metres at its interface. The chain is
world -> camera (R, T) -> undistorted sensor (f) -> distorted sensor (kappa1) -> pixels (sx, dpx, dpy, Cx, Cy).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from ...errors import UserError
from .xmlfile import xml_root

_FIELDS = {
    "Geometry": ("width", "height", "dpx", "dpy"),
    "Intrinsic": ("focal", "kappa1", "cx", "cy", "sx"),
    "Extrinsic": ("tx", "ty", "tz", "rx", "ry", "rz"),
}


class CalibrationError(UserError):
    """A calibration file is missing, unreadable or lacks a field; the message names the file and field."""


def euler_to_matrix(rx: float, ry: float, rz: float) -> np.ndarray:
    """Tsai's rotation (Willson ``calc_rr_from_euler``): world -> camera."""
    sa, ca = math.sin(rx), math.cos(rx)
    sb, cb = math.sin(ry), math.cos(ry)
    sg, cg = math.sin(rz), math.cos(rz)
    return np.array([
        [cb * cg, cg * sa * sb - ca * sg, sa * sg + ca * cg * sb],
        [cb * sg, sa * sb * sg + ca * cg, ca * sb * sg - cg * sa],
        [-sb, cb * sa, ca * cb],
    ])


@dataclasses.dataclass(frozen=True)
class TsaiCamera:
    """A calibrated Tsai camera. Lengths in mm internally (as in the file), metres at the public methods."""

    width: int
    height: int
    focal: float  # mm
    kappa1: float  # 1/mm^2
    cx: float  # px
    cy: float  # px
    sx: float  # horizontal scale factor
    dpx: float  # mm per pixel (effective, x)
    dpy: float  # mm per pixel (y)
    rot: np.ndarray  # (3, 3) world -> camera
    trans: np.ndarray  # (3,) mm
    scale: float = 1.0  # image resize factor applied to pixel coordinates (0.5 = half-size frames)

    @classmethod
    def from_xml(cls, path: str | Path) -> TsaiCamera:
        """Load a PETS ``<Camera><Geometry/><Intrinsic/><Extrinsic/></Camera>`` file."""
        path = Path(path)
        root = xml_root(path, CalibrationError, "a PETS Tsai calibration <Camera>", "calibration file")
        nodes = {tag: root.find(tag) for tag in _FIELDS}
        missing = [f"<{tag}>" for tag, node in nodes.items() if node is None]
        if missing:
            raise CalibrationError(f"{path}: missing {', '.join(missing)} element(s); expected a PETS Tsai "
                                   f"calibration <Camera> with <Geometry>, <Intrinsic> and <Extrinsic>")
        vals: dict[str, float] = {}
        for tag, names in _FIELDS.items():
            node = nodes[tag]
            for name in names:
                raw = node.get(name)
                if raw is None:
                    raise CalibrationError(f"{path}: <{tag}> lacks attribute {name!r}")
                try:
                    v = float(raw)
                except ValueError as exc:
                    raise CalibrationError(f"{path}: <{tag} {name}={raw!r}> is not a number") from exc
                if not math.isfinite(v):
                    raise CalibrationError(f"{path}: <{tag} {name}={raw!r}> is not finite")
                vals[f"{tag}.{name}"] = v
        for key in ("Geometry.dpx", "Geometry.dpy", "Intrinsic.focal", "Intrinsic.sx"):
            if vals[key] <= 0:
                raise CalibrationError(f"{path}: {key} = {vals[key]} must be > 0")
        return cls(width=int(vals["Geometry.width"]), height=int(vals["Geometry.height"]),
                   focal=vals["Intrinsic.focal"], kappa1=vals["Intrinsic.kappa1"], cx=vals["Intrinsic.cx"],
                   cy=vals["Intrinsic.cy"], sx=vals["Intrinsic.sx"], dpx=vals["Geometry.dpx"],
                   dpy=vals["Geometry.dpy"],
                   rot=euler_to_matrix(vals["Extrinsic.rx"], vals["Extrinsic.ry"], vals["Extrinsic.rz"]),
                   trans=np.array([vals["Extrinsic.tx"], vals["Extrinsic.ty"], vals["Extrinsic.tz"]]))

    def scaled(self, scale: float) -> TsaiCamera:
        """The same camera for frames resized by ``scale`` (pixel coordinates multiply by it)."""
        if not scale > 0:
            raise UserError(f"scale = {scale!r}: expected > 0")
        return dataclasses.replace(self, scale=self.scale * scale)

    # -- projections --------------------------------------------------------------------------------------
    def world_to_image(self, xyz: np.ndarray) -> np.ndarray:
        """World points (..., 3) or ground points (..., 2) in metres -> pixels (..., 2)."""
        xyz = np.asarray(xyz, dtype=float)
        if xyz.shape[-1] == 2:
            xyz = np.concatenate([xyz, np.zeros(xyz.shape[:-1] + (1,))], axis=-1)
        pc = (xyz * 1000.0) @ self.rot.T + self.trans
        xu = self.focal * pc[..., 0] / pc[..., 2]
        yu = self.focal * pc[..., 1] / pc[..., 2]
        # undistorted -> distorted: fixed point on Xd = Xu / (1 + k rd^2) (k rd^2 ~ 0.03 here)
        xd, yd = xu, yu
        for _ in range(20):
            f = 1.0 + self.kappa1 * (xd * xd + yd * yd)
            xd, yd = xu / f, yu / f
        u = xd * self.sx / self.dpx + self.cx
        v = yd / self.dpy + self.cy
        return np.stack([u, v], axis=-1) * self.scale

    def image_to_ground(self, uv: np.ndarray, z: float = 0.0) -> np.ndarray:
        """Pixels (..., 2) -> points (..., 2) in metres on the horizontal plane at height ``z`` m."""
        uv = np.asarray(uv, dtype=float) / self.scale
        xd = (uv[..., 0] - self.cx) * self.dpx / self.sx
        yd = (uv[..., 1] - self.cy) * self.dpy
        f = 1.0 + self.kappa1 * (xd * xd + yd * yd)
        ray_c = np.stack([xd * f, yd * f, np.full_like(xd, self.focal)], axis=-1)
        ray_w = ray_c @ self.rot  # R^T d
        centre = -self.rot.T @ self.trans  # camera centre in world mm
        t = (z * 1000.0 - centre[2]) / ray_w[..., 2]
        pts = centre[:2] + t[..., None] * ray_w[..., :2]
        return pts / 1000.0

    @property
    def centre_m(self) -> np.ndarray:
        """Camera optical centre in world coordinates (m)."""
        return -self.rot.T @ self.trans / 1000.0
