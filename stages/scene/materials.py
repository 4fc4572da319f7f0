"""PBR material library: UsdPreviewSurface materials with procedurally generated texture maps.

Kinds: floors (wood, tile, marble, carpet), walls (paint, brick, plaster, wallpaper) and one per
asset material class (wood grain, ceramic, fabric, metal, plastic, glass, stone, paper, rubber,
food). Each kind has texture maps generated with numpy from the scene's generator: base color
(sRGB PNG), roughness (raw, grey) and a tangent-space normal map (raw, from a height field); metals
also get a metallic map. A *look* picks a floor and a wall kind per room and a tint per material
(``UsdUVTexture.inputs:scale`` on the base color), so several looks share the same texture files;
the scene holds them as variants of one variant set (``look``) on ``/World``.

Texture size: ``TEXTURE_PX`` square. Textures tile every ``TILE_M`` meters on floors and walls
(``primvars:st`` authored on the layout meshes by planar projection).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from asset_catalog.materials import MATERIAL_RULES, MaterialClass

TEXTURE_PX = 128
TILE_M = 1.0
FLOOR_KINDS = ("wood", "tile", "marble", "carpet")
WALL_KINDS = ("paint", "brick", "plaster", "wallpaper")
ASSET_KINDS = tuple(f"asset_{m.value}" for m in MaterialClass)
METAL_KINDS = ("asset_metal",)


@dataclass(frozen=True)
class TextureSet:
    """Files of one material kind, relative to the scene folder (POSIX): base color, roughness,
    normal, metallic (or None); roughness/metallic values [0, 1] used as fallbacks."""

    kind: str
    base_color: str
    roughness: str
    normal: str
    metallic: str | None


@dataclass(frozen=True)
class MaterialChoice:
    """One material of a look: prim name, texture kind, tint (linear RGB multiplier of the base
    color texture), opacity [0, 1]."""

    name: str
    kind: str
    tint: tuple[float, float, float]
    opacity: float = 1.0


@dataclass(frozen=True)
class Look:
    """One variant: per room id its floor and wall material, per asset material class its material."""

    name: str
    floors: dict[str, MaterialChoice]
    walls: dict[str, MaterialChoice]
    assets: dict[str, MaterialChoice]

    def materials(self) -> list[MaterialChoice]:
        seen: dict[str, MaterialChoice] = {}
        for m in (*self.floors.values(), *self.walls.values(), *self.assets.values()):
            seen.setdefault(m.name, m)
        return list(seen.values())


# ---------------------------------------------------------------------------------------------
# procedural maps


def _noise(rng: np.random.Generator, n: int, cells: int) -> np.ndarray:
    """Tileable value noise in [0, 1], (n, n), ``cells`` lattice cells per side (bilinear)."""
    g = rng.random((cells, cells))
    x = np.arange(n) * cells / n
    i0 = np.floor(x).astype(int)
    f = x - i0
    f = f * f * (3 - 2 * f)
    i1 = (i0 + 1) % cells
    a = g[i0][:, i0] * (1 - f)[None, :] + g[i0][:, i1] * f[None, :]
    b = g[i1][:, i0] * (1 - f)[None, :] + g[i1][:, i1] * f[None, :]
    return a * (1 - f)[:, None] + b * f[:, None]


def _fbm(rng: np.random.Generator, n: int, base: int = 4, octaves: int = 4) -> np.ndarray:
    out, amp, tot = np.zeros((n, n)), 1.0, 0.0
    for o in range(octaves):
        out += amp * _noise(rng, n, base * 2 ** o)
        tot += amp
        amp *= 0.5
    return out / tot


def _height_and_color(kind: str, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(height (n, n) in [0, 1], base color (n, n, 3) in [0, 1], roughness (n, n) in [0, 1])."""
    u = np.arange(n) / n
    U, V = np.meshgrid(u, u)
    fb = _fbm(rng, n)

    def mix(c0, c1, t):
        return np.asarray(c0)[None, None] * (1 - t[..., None]) + np.asarray(c1)[None, None] * t[..., None]

    if kind in ("wood", "asset_wood"):
        rings = 0.5 + 0.5 * np.sin((V * 6 + fb * 2.5) * 2 * np.pi * 3)
        planks = (np.floor(U * 4) % 2) * 0.08
        h = rings * 0.3 + ((U * 4) % 1 < 0.02) * -0.6 + 0.5
        col = mix((0.45, 0.28, 0.14), (0.7, 0.5, 0.3), np.clip(rings * 0.7 + planks + fb * 0.3, 0, 1))
        rough = 0.45 + 0.25 * rings
    elif kind == "tile":
        grout = ((U * 4) % 1 < 0.04) | ((V * 4) % 1 < 0.04)
        h = np.where(grout, 0.0, 0.8 + 0.1 * fb)
        col = np.where(grout[..., None], 0.55, mix((0.85, 0.85, 0.82), (0.95, 0.95, 0.93), fb))
        rough = np.where(grout, 0.9, 0.2)
    elif kind in ("marble", "asset_stone"):
        veins = np.abs(np.sin((U + V + fb * 1.8) * 2 * np.pi * 2)) ** 0.3
        h = 0.5 + 0.05 * fb
        col = mix((0.35, 0.35, 0.38), (0.93, 0.92, 0.9), veins)
        rough = 0.15 + 0.2 * (1 - veins)
    elif kind in ("carpet", "asset_fabric"):
        fine = _noise(rng, n, n // 2)
        weave = 0.5 + 0.25 * np.sin(U * n * np.pi / 2) * np.sin(V * n * np.pi / 2)
        h = 0.5 * fine + 0.5 * weave
        col = mix((0.35, 0.35, 0.38), (0.6, 0.6, 0.62), 0.6 * fb + 0.4 * fine)
        rough = 0.85 + 0.1 * fine
    elif kind == "brick":
        row = np.floor(V * 8)
        off = (row % 2) * 0.5
        mortar = ((V * 8) % 1 < 0.08) | (((U * 4 + off) % 1) < 0.04)
        h = np.where(mortar, 0.0, 0.7 + 0.3 * fb)
        col = np.where(mortar[..., None], 0.75, mix((0.5, 0.2, 0.12), (0.7, 0.35, 0.22), fb))
        rough = np.where(mortar, 0.95, 0.8)
    elif kind == "plaster":
        h = _fbm(rng, n, base=8, octaves=5)
        col = mix((0.85, 0.83, 0.8), (0.95, 0.94, 0.92), h)
        rough = 0.8 + 0.15 * h
    elif kind == "wallpaper":
        stripes = (0.5 + 0.5 * np.sin(U * 2 * np.pi * 8)) ** 4
        h = 0.5 + 0.05 * fb
        col = mix((0.8, 0.78, 0.7), (0.6, 0.55, 0.45), stripes)
        rough = 0.7 + 0.0 * h
    elif kind == "paint":
        h = 0.5 + 0.03 * _noise(rng, n, 32)
        col = mix((0.9, 0.9, 0.88), (0.94, 0.94, 0.92), fb)
        rough = 0.75 + 0.05 * fb
    elif kind == "asset_metal":
        brushed = _noise(rng, n, 64)[:, :1].repeat(n, axis=1)
        h = 0.5 + 0.1 * brushed
        col = mix((0.6, 0.6, 0.62), (0.8, 0.8, 0.82), brushed)
        rough = 0.25 + 0.15 * brushed
    else:  # ceramic, plastic, glass, paper, rubber, food: smooth with mild variation
        rule = MATERIAL_RULES[MaterialClass(kind.removeprefix("asset_"))]
        h = 0.5 + 0.02 * fb
        base = np.asarray(rule.base_color)
        col = mix(base * 0.9, np.minimum(base * 1.1, 1.0), fb)
        rough = np.full((n, n), rule.roughness) + 0.05 * (fb - 0.5)
    return h, np.clip(col, 0, 1), np.clip(rough, 0, 1)


def _normal_map(h: np.ndarray, strength: float = 2.0) -> np.ndarray:
    """Tangent-space normals (n, n, 3) in [0, 1] encoding of a tileable height field."""
    dx = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) * strength
    dy = (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0)) * strength
    nrm = np.stack([-dx, -dy, np.ones_like(h)], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return nrm * 0.5 + 0.5


def write_textures(kinds: list[str], out_dir: Path, rng: np.random.Generator, *, px: int = TEXTURE_PX,
                   rel_to: Path | None = None) -> dict[str, TextureSet]:
    """Generate and write the maps of each kind into ``out_dir`` (PNG); paths relative to ``rel_to``
    (default: out_dir's parent)."""
    from PIL import Image

    out_dir.mkdir(parents=True, exist_ok=True)
    base = rel_to or out_dir.parent
    out = {}
    for kind in kinds:
        h, col, rough = _height_and_color(kind, rng, px)
        srgb = np.where(col <= 0.0031308, col * 12.92, 1.055 * np.power(col, 1 / 2.4) - 0.055)
        files = {"base_color": srgb, "roughness": rough, "normal": _normal_map(h)}
        if kind in METAL_KINDS:
            files["metallic"] = np.full_like(rough, 1.0) - 0.1 * (rough - rough.mean())
        paths = {}
        for name, arr in files.items():
            p = out_dir / f"{kind}_{name}.png"
            img = (np.clip(arr, 0, 1) * 255 + 0.5).astype(np.uint8)
            Image.fromarray(img).save(p, optimize=False, compress_level=1)  # fast zlib: 3x less encode time
            paths[name] = p.relative_to(base).as_posix()
        out[kind] = TextureSet(kind, paths["base_color"], paths["roughness"], paths["normal"], paths.get("metallic"))
    return out


# ---------------------------------------------------------------------------------------------
# looks


def _tint(rng: np.random.Generator, spread: float) -> tuple[float, float, float]:
    t = 1.0 + rng.uniform(-spread, spread, 3)
    return tuple(float(x) for x in np.clip(t * rng.uniform(0.8, 1.1), 0.2, 1.0))


def sample_looks(room_ids: list[str], asset_classes: list[str], n_looks: int, rng: np.random.Generator) -> list[Look]:
    """``n_looks`` looks: per room a floor and wall kind with a tint; per asset class a tint."""
    looks = []
    for k in range(n_looks):
        floors, walls, assets = {}, {}, {}
        for r in room_ids:
            fk = FLOOR_KINDS[int(rng.integers(len(FLOOR_KINDS)))]
            wk = WALL_KINDS[int(rng.integers(len(WALL_KINDS)))]
            floors[r] = MaterialChoice(f"L{k}_floor_{r}", fk, _tint(rng, 0.15))
            walls[r] = MaterialChoice(f"L{k}_wall_{r}", wk, _tint(rng, 0.2))
        for c in asset_classes:
            assets[c] = MaterialChoice(f"L{k}_asset_{c}", f"asset_{c}", _tint(rng, 0.25),
                                       opacity=0.35 if c == MaterialClass.GLASS.value else 1.0)
        looks.append(Look(f"look_{k}", floors, walls, assets))
    return looks


def planar_st(points: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Face-varying texture coordinates (3M, 2) for a triangle mesh: each triangle projected on the
    plane its normal is closest to, in units of TILE_M."""
    tri = points[indices.reshape(-1, 3)]
    n = np.abs(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    axis = np.argmax(n, axis=1)
    keep = np.array([[1, 2], [0, 2], [0, 1]])[axis]  # drop the dominant axis
    st = np.take_along_axis(tri, np.repeat(keep[:, None, :], 3, axis=1), axis=2)
    return (st.reshape(-1, 2) / TILE_M).astype(np.float32)
