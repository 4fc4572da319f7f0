"""Helpers of the ingest tests: small real source files written into a temporary catalog folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
SHARED_RIGID_ANNOTATIONS = REPO / "tests" / "data" / "shared_rigid" / "annotations.toml"


def write_obj(path: Path, vertices, faces, *, mtl: str | None = None, uvs=None) -> Path:
    """A Wavefront OBJ (1-based faces); optional ``mtllib`` and per-vertex UVs."""
    lines = [f"mtllib {mtl}"] if mtl else []
    lines += [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in np.asarray(vertices, dtype=float)]
    if uvs is not None:
        lines += [f"vt {float(u)!r} {float(v)!r}" for u, v in uvs]
        lines.append("usemtl mat0")
        lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in faces]
    else:
        if mtl:
            lines.append("usemtl mat0")
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def box_arrays(size=(0.1, 0.1, 0.1)):
    import trimesh

    b = trimesh.creation.box(extents=size)
    return np.asarray(b.vertices), np.asarray(b.faces)


def write_textured_box(folder: Path, name: str = "box", *, texture: bool = True,
                       size=(0.1, 0.1, 0.1)) -> Path:
    """box.obj + box.mtl (+ box.png): a textured box with per-vertex UVs."""
    from PIL import Image

    v, f = box_arrays(size)
    uvs = (v[:, :2] - v[:, :2].min(0)) / np.ptp(v[:, :2], axis=0)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.mtl").write_text(f"newmtl mat0\nKd 0.8 0.6 0.4\nmap_Kd {name}.png\n", encoding="utf-8")
    if texture:
        Image.new("RGB", (8, 8), (200, 120, 40)).save(folder / f"{name}.png")
    return write_obj(folder / f"{name}.obj", v, f, mtl=f"{name}.mtl", uvs=uvs)


def write_stl(path: Path, mesh) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh.export(path)
    return path


def bowl_mesh(radius: float = 0.07, wall: float = 0.008, sections: int = 24):
    """A closed, thick-walled hemispherical bowl (opening up, bottom at z = 0), a few hundred faces."""
    import trimesh

    t_out = np.linspace(np.pi / 2, np.pi, 8)           # outer profile: rim down to the bottom pole
    outer = np.stack([radius * np.sin(t_out), radius + radius * np.cos(t_out)], axis=1)
    t_in = np.linspace(np.pi, np.pi / 2, 8)            # inner profile: bottom back up to the rim
    r_in = radius - wall
    inner = np.stack([r_in * np.sin(t_in), radius + r_in * np.cos(t_in)], axis=1)
    inner[0, 0] = 0.0
    outer[-1, 0] = 0.0
    profile = np.concatenate([outer, inner, outer[:1]])
    mesh = trimesh.creation.revolve(profile, sections=sections)
    mesh.merge_vertices()
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def shelf_mesh(width: float = 0.6, depth: float = 0.3, height: float = 0.8, board: float = 0.02,
               shelves: int = 3):
    """An open bookshelf as one mesh of separate boards (sides, back, top/bottom and shelves)."""
    import trimesh

    boards = [
        trimesh.creation.box((board, depth, height), trimesh.transformations.translation_matrix(
            (-(width - board) / 2, 0, height / 2))),
        trimesh.creation.box((board, depth, height), trimesh.transformations.translation_matrix(
            ((width - board) / 2, 0, height / 2))),
        trimesh.creation.box((width - 2 * board, board, height), trimesh.transformations.translation_matrix(
            (0, (depth - board) / 2, height / 2))),
    ]
    for z in np.linspace(board / 2, height - board / 2, shelves + 1):
        boards.append(trimesh.creation.box((width - 2 * board, depth - board, board),
                                           trimesh.transformations.translation_matrix((0, -board / 2, z))))
    return trimesh.util.concatenate(boards)
