"""Materials of mesh sources (see ``stages.loaders.mesh``): OBJ materials from their MTL files, glTF
materials from the glTF JSON (ORM channels split into grayscale maps), trimesh materials no source
names, and the content-addressed cache of derived textures. Texture paths never escape the catalog
folder; a missing or unreadable texture is an ItemError naming the file.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import struct
from io import BytesIO
from pathlib import Path

import numpy as np

from asset_catalog.asset_model import MaterialSpec
from pipeline.types import ItemError
from stages.loaders._source import _one_line, _sha256_file


def _from_trimesh_material(mat, cache: Path) -> MaterialSpec | None:
    """A MaterialSpec from a trimesh material whose source could not be matched by name (PIL images
    are written to the texture cache)."""
    name = getattr(mat, "name", None) or "material"
    base = getattr(mat, "baseColorFactor", None)
    if base is None:
        base = getattr(mat, "diffuse", None)
    color = (0.8, 0.8, 0.8)
    opacity = 1.0
    if base is not None:
        b = np.asarray(base, dtype=np.float64)
        b = b / 255.0 if b.max() > 1.0 else b
        color = tuple(float(x) for x in b[:3])
        opacity = float(b[3]) if len(b) > 3 else 1.0
    img = getattr(mat, "baseColorTexture", None) or getattr(mat, "image", None)
    tex = _cache_pil(img, cache) if img is not None else None
    rough = getattr(mat, "roughnessFactor", None)
    metal = getattr(mat, "metallicFactor", None)
    return MaterialSpec(name=name, base_color=color if tex is None else (1.0, 1.0, 1.0), opacity=opacity,
                        roughness=0.5 if rough is None else float(rough),
                        metallic=0.0 if metal is None else float(metal), base_color_texture=tex)


def _cache_bytes(data: bytes, suffix: str, cache: Path) -> Path:
    cache.mkdir(parents=True, exist_ok=True)
    out = cache / f"{hashlib.sha256(data).hexdigest()[:32]}{suffix}"
    if not out.exists():
        tmp = out.with_name(out.name + f".{os.getpid()}.{id(data)}.tmp")
        tmp.write_bytes(data)
        tmp.replace(out)
    return out


def _cache_pil(img, cache: Path) -> Path:
    buf = BytesIO()
    img.save(buf, format="PNG")
    return _cache_bytes(buf.getvalue(), ".png", cache)


def _check_texture(base: Path, ref: str, root: Path, referrer: Path, what: str) -> Path:
    """The resolved path of texture ``ref`` (relative to ``base``), inside ``root``, existing and
    decodable; else ItemError naming the referring file and the texture as written."""
    from PIL import Image, UnidentifiedImageError

    p = (base / ref).resolve()
    if not p.is_relative_to(root):
        raise ItemError(f"{referrer}: {what} '{ref}' escapes the catalog folder")
    if not p.is_file():
        raise ItemError(f"{referrer}: {what} '{ref}' not found (looked for {p})")
    try:
        with Image.open(p) as im:
            im.verify()
    except (UnidentifiedImageError, OSError, SyntaxError) as e:
        raise ItemError(f"{referrer}: {what} '{ref}' is unreadable: {_one_line(e)}") from e
    return p


# --- OBJ / MTL

_MTL_MAPS = {"map_kd": "base", "map_bump": "normal", "bump": "normal", "norm": "normal", "map_pr": "rough",
             "map_pm": "metal"}


def _mtllib_names(obj: Path) -> list[str]:
    names: list[str] = []
    with obj.open("r", encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.startswith("mtllib"):
                rest = line[6:].strip()
                if rest:
                    names.append(rest.replace("\\", "/"))
    return names


def _strip_map_options(tokens: list[str]) -> str:
    """The file name of an MTL ``map_*`` statement, after options such as ``-bm 1.0`` or ``-s 1 1 1``."""
    i = 0
    while i < len(tokens) and tokens[i].startswith("-"):
        i += 1
        while i < len(tokens) - 1 and (_is_number(tokens[i]) or tokens[i] in ("on", "off")):
            i += 1
        if i < len(tokens) - 1 and len(tokens[i]) == 1 and tokens[i - 1] == "-imfchan":
            i += 1
    return " ".join(tokens[i:]).replace("\\", "/")


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _parse_mtl(mtl: Path) -> list[tuple[str, str]]:
    """(statement, texture file) pairs of an MTL file's texture maps."""
    out: list[tuple[str, str]] = []
    for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
        tokens = line.split()
        if tokens and tokens[0].lower() in _MTL_MAPS and len(tokens) > 1:
            out.append((tokens[0].lower(), _strip_map_options(tokens[1:])))
    return out


def _obj_materials(obj: Path, root: Path) -> dict[str, MaterialSpec]:
    """MaterialSpecs of every material in the OBJ's MTL libraries; textures checked."""
    specs: dict[str, MaterialSpec] = {}
    for lib in _mtllib_names(obj):
        mtl = (obj.parent / lib)
        if not mtl.resolve().is_relative_to(root):
            raise ItemError(f"{obj}: material library '{lib}' escapes the catalog folder")
        if not mtl.is_file():
            raise ItemError(f"{obj}: material library '{lib}' not found")
        specs.update(_read_mtl(mtl, root))
    return specs


def _read_mtl(mtl: Path, root: Path) -> dict[str, MaterialSpec]:
    specs: dict[str, MaterialSpec] = {}
    cur: dict | None = None

    def close() -> None:
        if cur is not None:
            specs[cur["name"]] = _mtl_spec(cur)

    for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        key = tokens[0].lower()
        if key == "newmtl":
            close()
            cur = {"name": " ".join(tokens[1:]) or "material"}
        elif cur is None:
            continue
        elif key in ("kd", "d", "ns", "pr", "pm", "tr") and len(tokens) > 1:
            try:
                cur[key] = [float(t) for t in tokens[1:4]]
            except ValueError:
                raise ItemError(f"{mtl}: bad number in '{line.strip()}'") from None
        elif key in _MTL_MAPS and len(tokens) > 1:
            tex = _strip_map_options(tokens[1:])
            cur[_MTL_MAPS[key]] = _check_texture(mtl.parent, tex, root, mtl, "texture")
    close()
    return specs


def _mtl_spec(m: dict) -> MaterialSpec:
    kd = m.get("kd")
    color = tuple(float(np.clip(x, 0, 1)) for x in (kd + kd[:1] * 2)[:3]) if kd else (0.8, 0.8, 0.8)
    if "base" in m and not kd:
        color = (1.0, 1.0, 1.0)
    opacity = m["d"][0] if "d" in m else (1.0 - m["tr"][0] if "tr" in m else 1.0)
    if "pr" in m:
        rough = m["pr"][0]
    elif "ns" in m:
        rough = float(np.sqrt(2.0 / (max(m["ns"][0], 0.0) + 2.0)))  # Blinn-Phong exponent -> roughness
    else:
        rough = 0.5
    return MaterialSpec(name=m["name"], base_color=color, opacity=float(np.clip(opacity, 0, 1)),
                        roughness=float(np.clip(rough, 0.0, 1.0)),
                        metallic=float(np.clip(m["pm"][0], 0, 1)) if "pm" in m else 0.0,
                        base_color_texture=m.get("base"), normal_texture=m.get("normal"),
                        roughness_texture=m.get("rough"), metallic_texture=m.get("metal"))


# --- glTF / GLB


def _uri_path(uri: str) -> str:
    from urllib.parse import unquote

    return unquote(uri).replace("\\", "/")


def _read_gltf_json(path: Path) -> tuple[dict, bytes | None]:
    """The glTF JSON document and, for GLB, the binary chunk."""
    data = path.read_bytes()
    try:
        if path.suffix.lower() == ".glb":
            if len(data) < 20 or data[:4] != b"glTF":
                raise ItemError(f"{path}: not a GLB file (bad header)")
            jlen, jtype = struct.unpack_from("<II", data, 12)
            doc = json.loads(data[20:20 + jlen].decode("utf-8"))
            off = 20 + jlen
            binary = None
            if off + 8 <= len(data):
                blen, _ = struct.unpack_from("<II", data, off)
                binary = data[off + 8: off + 8 + blen]
            return doc, binary
        return json.loads(data.decode("utf-8")), None
    except (ValueError, UnicodeDecodeError, struct.error) as e:
        raise ItemError(f"{path}: unreadable glTF JSON: {_one_line(e)}") from e


def _gltf_materials(path: Path, root: Path, cache: Path) -> dict[str, MaterialSpec]:
    """MaterialSpecs by glTF material name; external buffers/images checked; ORM channels split."""
    doc, binary = _read_gltf_json(path)
    for buf in doc.get("buffers", []):
        uri = buf.get("uri")
        if uri and not uri.startswith("data:"):
            bp = path.parent / _uri_path(uri)
            if not bp.resolve().is_relative_to(root):
                raise ItemError(f"{path}: buffer '{uri}' escapes the catalog folder")
            if not bp.is_file():
                raise ItemError(f"{path}: buffer '{uri}' not found")
    images = [_gltf_image(doc, i, path, root, binary, cache) for i in range(len(doc.get("images", [])))]
    textures = doc.get("textures", [])

    def tex_image(info: dict | None) -> Path | None:
        if not info or "index" not in info:
            return None
        try:
            t = textures[info["index"]]
        except (IndexError, TypeError):
            raise ItemError(f"{path}: texture index {info.get('index')} out of range") from None
        src = t.get("source")
        if src is None:
            src = t.get("extensions", {}).get("KHR_texture_basisu", {}).get("source")
        if src is None or not 0 <= src < len(images):
            raise ItemError(f"{path}: texture {info['index']} has no usable image")
        return images[src]

    specs: dict[str, MaterialSpec] = {}
    names = [m.get("name") for m in doc.get("materials", [])]
    for m in doc.get("materials", []):
        name = m.get("name")
        if not name or names.count(name) > 1:
            continue  # ambiguous by name: built from trimesh's copy instead
        specs[name] = _gltf_spec(m, tex_image, cache, path)
    return specs


def _gltf_image(doc: dict, i: int, path: Path, root: Path, binary: bytes | None, cache: Path) -> Path | None:
    img = doc["images"][i]
    uri = img.get("uri")
    if uri and uri.startswith("data:"):
        try:
            data = base64.b64decode(uri.split(",", 1)[1])
        except (ValueError, IndexError) as e:
            raise ItemError(f"{path}: image {i}: bad data URI") from e
        return _checked_cached_image(data, path, f"embedded image {i}", cache)
    if uri:
        if uri.lower().endswith(".ktx2"):
            return None  # KTX2 (basisu) images are used only through a PNG/JPEG fallback
        return _check_texture(path.parent, _uri_path(uri), root, path, "texture")
    bv = img.get("bufferView")
    if bv is None or binary is None:
        raise ItemError(f"{path}: image {i} has neither a URI nor an embedded buffer view")
    view = doc["bufferViews"][bv]
    off = int(view.get("byteOffset", 0))
    data = binary[off: off + int(view["byteLength"])]
    return _checked_cached_image(data, path, f"embedded image {i}", cache)


def _checked_cached_image(data: bytes, path: Path, what: str, cache: Path) -> Path:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(BytesIO(data)) as im:
            fmt = (im.format or "PNG").lower()
            im.verify()
    except (UnidentifiedImageError, OSError, SyntaxError) as e:
        raise ItemError(f"{path}: {what} is unreadable: {_one_line(e)}") from e
    return _cache_bytes(data, ".jpg" if fmt == "jpeg" else f".{fmt}", cache)


def _gltf_spec(m: dict, tex_image, cache: Path, path: Path) -> MaterialSpec:
    pbr = m.get("pbrMetallicRoughness", {})
    base = [float(x) for x in pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])]
    metallic = float(pbr.get("metallicFactor", 1.0))
    rough = float(pbr.get("roughnessFactor", 1.0))
    mr = tex_image(pbr.get("metallicRoughnessTexture"))
    occ = tex_image(m.get("occlusionTexture"))
    rough_tex = _channel(mr, 1, rough, cache, path) if mr is not None else None
    metal_tex = _channel(mr, 2, metallic, cache, path) if mr is not None and metallic > 0.0 else None
    occ_tex = _channel(occ, 0, 1.0, cache, path) if occ is not None else None
    opacity = base[3] if m.get("alphaMode", "OPAQUE") != "OPAQUE" else 1.0
    return MaterialSpec(name=m.get("name") or "material", base_color=tuple(base[:3]), opacity=opacity,
                        roughness=rough, metallic=metallic,
                        base_color_texture=tex_image(pbr.get("baseColorTexture")),
                        normal_texture=tex_image(m.get("normalTexture")), roughness_texture=rough_tex,
                        metallic_texture=metal_tex, occlusion_texture=occ_tex)


def _channel(image: Path, channel: int, factor: float, cache: Path, path: Path) -> Path:
    """One channel (0 R, 1 G, 2 B) of ``image`` times ``factor`` as a grayscale PNG in the cache."""
    from PIL import Image

    key = hashlib.sha256(f"{_sha256_file(image)}:{channel}:{factor!r}".encode()).hexdigest()[:32]
    out = cache / f"{key}.png"
    if out.exists():
        return out
    try:
        with Image.open(image) as im:
            bands = im.convert("RGB").split()
    except OSError as e:
        raise ItemError(f"{path}: texture '{image}' is unreadable: {_one_line(e)}") from e
    band = bands[channel]
    if factor != 1.0:
        band = band.point(lambda x: int(round(min(255.0, x * factor))))
    buf = BytesIO()
    band.save(buf, format="PNG")
    cache.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + f".{os.getpid()}.{id(buf)}.tmp")
    tmp.write_bytes(buf.getvalue())
    tmp.replace(out)
    return out
