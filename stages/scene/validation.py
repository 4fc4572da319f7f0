"""USD validation of a composed scene: each package once, per scene only what composition adds.

A scene is the layout layer and many asset packages (shared by every scene that uses them) plus the
scene's own layers (root, lighting, materials, placement). ``validate_scene``:

1. validates every package the scene references, and the layout layer, with
   ``usd_schemas.validate_package`` (composition, usd-core's validators, omniverse-asset-validator)
   once per package content: the result is kept in a ``CheckCache`` (kind ``validation``) keyed by
   the package folder's content hash, so an unchanged package is never validated twice;
2. checks what the scene's layers add, on the scene stage composed without payloads (the packages'
   geometry; its own opinions all compose): the composition errors (every sublayer, layout and
   package reference resolves) and every usd-core validator (material bindings, shaders, physics,
   stage metadata, ...) once per ``look`` variant;
3. runs omniverse-asset-validator on the scene's own prims (materials, lights, physics scene) and its
   layers, but only on the structures not seen before: each prim tree under /World/Looks,
   /World/Lights, /World/PhysicsScene and the layer metadata get a signature (prim types, applied
   schemas, properties, connections, token values, asset paths found or not, every number exactly
   except those of the attributes that vary from scene to scene by design (``VARYING``: placement
   transforms, light intensity, exposure, color temperature and size, material tints, the scale and
   bias of texture readers other than normal maps), which enter by class: finite, in [0, 1]); a signature is validated once (kind ``structure`` in the
   cache, keyed also by the validator's version) and its result reused, so a material differing
   only in its tint is not validated again. The layer metadata (metersPerUnit, upAxis, ...) and
   the values the validator checks (a normal map's scale and bias, masses) enter exactly.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
from collections.abc import Sequence
from pathlib import Path

from pydantic import BaseModel, ConfigDict

from stages.scene.checkcache import CheckCache, content_hash

log = logging.getLogger(__name__)

OWN_ROOTS = ("/World/Looks", "/World/Lights")
PHYSICS_SCENE = "/World/PhysicsScene"
# attributes whose numbers enter a structure's signature by class only (see the module docstring);
# omniverse-asset-validator checks none of their values beyond finiteness (the scale and bias of a
# texture reader too, unless it feeds a normal input: NormalMapTextureChecker checks those)
VARYING = frozenset({"inputs:intensity", "inputs:exposure", "inputs:colorTemperature", "inputs:radius",
                     "inputs:angle", "inputs:width", "inputs:height", "inputs:length", "inputs:color",
                     "inputs:diffuseColor", "inputs:emissiveColor", "inputs:roughness", "inputs:metallic",
                     "inputs:opacity", "inputs:specularColor", "inputs:clearcoat", "inputs:clearcoatRoughness"})


class SceneValidation(BaseModel):
    """errors: one line each (packages' errors prefixed with the package file); warnings: count;
    packages: packages (and layout) the scene uses; packages_validated: of those, validated now
    (the others came from the cache); structures_validated: scene structures validated now."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    errors: tuple[str, ...]
    warnings: int
    packages: int
    packages_validated: int
    structures_validated: int


def validate_package_cached(root_layer: Path, cache: CheckCache) -> tuple[dict, bool]:
    """({"errors": [lines], "warnings": n}, validated now) of the package whose root layer is
    ``root_layer``; the package is its folder."""
    from usd_schemas import validate_package

    key = content_hash(Path(root_layer).parent)
    got = cache.get("validation", key)
    if got is not None:
        return got, False
    rep = validate_package(Path(root_layer))
    val = {"errors": [i.line() for i in rep.errors], "warnings": len(rep.warnings), "file": Path(root_layer).name}
    cache.put("validation", key, val)
    return val, True


def validate_scene(scene_usd: Path, packages: Sequence[Path], cache: CheckCache) -> SceneValidation:
    """See the module docstring. ``packages``: root layers of the asset packages and the layout
    layer the scene references."""
    from pxr import Usd

    import usd_schemas  # noqa: F401  (schema registry)
    from usd_schemas._validate import _composition_issues, _usd_validator_issues

    errors: list[str] = []
    warnings = 0
    fresh = 0
    uniq = sorted({Path(p).resolve() for p in packages})
    for p in uniq:
        val, now = validate_package_cached(p, cache)
        fresh += now
        errors += [f"{p.name}: {e}" for e in val["errors"]]
        warnings += int(val["warnings"])

    stage = Usd.Stage.Open(str(scene_usd), Usd.Stage.LoadNone)
    errors += [i.line() for i in _composition_issues(stage)]
    stage.SetEditTarget(stage.GetSessionLayer())  # variant switches stay out of the scene's layers
    world = stage.GetDefaultPrim()
    vset = world.GetVariantSet("look") if world and world.GetVariantSets().HasVariantSet("look") else None
    per_look, once = _split_validators()
    fixed = None  # issues of the validators that read only the root layer's files: the same for every look
    for v in (vset.GetVariantNames() if vset else [None]):
        if vset is not None:
            vset.SetVariantSelection(v)
        if fixed is None:
            fixed = _usd_validator_issues(stage, once) if once else []
        for i in _usd_validator_issues(stage, per_look) + fixed:
            if i.severity == "error":
                errors.append(f"look {v}: {i.line()}" if v else i.line())
            elif i.severity == "warning":
                warnings += 1
    if vset is not None:
        stage.GetSessionLayer().Clear()

    new: dict[str, str] = {}   # signature key -> representative prim path ("" for the layers)
    sigs = _signatures(stage, Path(scene_usd))
    results: list[dict] = []
    for key, path in sigs.items():
        got = cache.get("structure", key)
        if got is None:
            new.setdefault(key, path)
        else:
            results.append(got)
    if new:
        results += _omni_structures(Path(scene_usd), new, cache)
    for r in results:
        errors += r["errors"]
        warnings += int(r["warnings"])
    return SceneValidation(errors=tuple(errors), warnings=warnings, packages=len(uniq), packages_validated=fresh,
                           structures_validated=len(new))


# usd-core validators that read only the files below the stage's root layer identifier (its asset
# dependencies, package files), never the composed stage: a variant selection (in the session
# layer) cannot change their result, so they run once per scene, not once per look
ROOT_LAYER_VALIDATORS = frozenset({
    "usdUtilsValidators:MissingReferenceValidator", "usdUtilsValidators:UsdzPackageValidator",
    "usdUtilsValidators:PackageEncapsulationValidator", "usdUtilsValidators:RootPackageValidator",
    "usdUtilsValidators:FileExtensionValidator"})


def _split_validators() -> tuple[list, list]:
    """(validators run for every look, validators run once: ROOT_LAYER_VALIDATORS)."""
    from pxr import UsdValidation

    every = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    once = [v for v in every if v.GetMetadata().name in ROOT_LAYER_VALIDATORS]
    return [v for v in every if v.GetMetadata().name not in ROOT_LAYER_VALIDATORS], once


def _omni_structures(scene_usd: Path, new: dict[str, str], cache: CheckCache) -> list[dict]:
    """omniverse-asset-validator on the scene masked to the representatives of new signatures
    (variants not expanded: bindings are checked per variant by usd-core's validators); the issues
    are filed under the signature whose prim they are at (the rest under the layers' signature)."""
    from pxr import Usd

    from usd_schemas._validate import DISABLED_OMNI_RULES

    from omni.asset_validator import IssueSeverity, ValidationEngine

    paths = sorted({p for p in new.values() if p})
    stage = Usd.Stage.OpenMasked(str(scene_usd), Usd.StagePopulationMask(paths or [PHYSICS_SCENE]),
                                 Usd.Stage.LoadNone)
    engine = _engine(ValidationEngine, DISABLED_OMNI_RULES)
    out: dict[str, dict] = {k: {"errors": [], "warnings": 0} for k in new}
    layers_key = next((k for k, p in new.items() if not p), None)
    for issue in engine.validate(stage).issues():
        if issue.severity in (IssueSeverity.NONE, IssueSeverity.INFO):
            continue
        at = "" if issue.at is None else str(getattr(issue.at, "path", None) or issue.at)
        key = next((k for k, p in new.items() if p and (at == p or at.startswith(p + "/") or at.startswith(p + "."))),
                   layers_key)
        if key is None:
            key = next(iter(new))
        rule = issue.rule.__name__ if issue.rule is not None else "engine"
        if issue.severity in (IssueSeverity.ERROR, IssueSeverity.FAILURE):
            out[key]["errors"].append(f"[error] omni:{rule}{' at ' + at if at else ''}: {' '.join(str(issue.message).split())}")
        else:
            out[key]["warnings"] += 1
    for k, v in out.items():
        cache.put("structure", k, v)
    return list(out.values())


_ENGINES: list = []


def _engine(cls, disabled):
    if not _ENGINES:
        e = cls(init_rules=True, variants=False)
        for rule in list(e.enabled_rules):
            if rule.__name__ in disabled:
                e.disable_rule(rule)
        _ENGINES.append(e)
    return _ENGINES[0]


def _signatures(stage, scene_usd: Path) -> dict[str, str]:
    """{signature key: representative prim path} of the scene's own structures: each child of
    OWN_ROOTS, the physics scene, and ("" path) the layers' metadata."""
    out: dict[str, str] = {}
    roots = []
    for r in OWN_ROOTS:
        prim = stage.GetPrimAtPath(r)
        if prim:
            roots += list(prim.GetChildren())
    ps = stage.GetPrimAtPath(PHYSICS_SCENE)
    if ps:
        roots.append(ps)
    for prim in roots:
        sig = _prim_tree_signature(prim)
        out.setdefault(_key(sig), str(prim.GetPath()))
    layers = []
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        info = {k: _exact(layer.pseudoRoot.GetInfo(k)) for k in layer.pseudoRoot.ListInfoKeys()
                if k not in ("customLayerData", "documentation", "comment", "subLayerOffsets")}
        layers.append([Path(layer.realPath or layer.identifier).name, layer.GetFileFormat().formatId, info])
    out.setdefault(_key(["layers", layers]), "")
    return out


def _key(sig) -> str:
    return hashlib.sha256(json.dumps([_validator_version(), sig], sort_keys=True, default=str).encode()).hexdigest()


@functools.cache  # a package's metadata lookup scans sys.path: once per process
def _validator_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("omniverse-asset-validator")
    except PackageNotFoundError:
        return "unknown"


def _exact(v) -> object:
    """A value as it is (asset paths by whether they resolve and their extension: a scene's
    folder differs from scene to scene)."""
    from pxr import Sdf

    if v is None or isinstance(v, (bool, str, int, float)):
        return v
    if isinstance(v, Sdf.AssetPath):
        return ["asset", bool(v.resolvedPath), Path(v.path).suffix]
    if isinstance(v, dict):
        return {str(k): _exact(x) for k, x in v.items()}
    if hasattr(v, "GetReal"):
        return ["quat", float(v.GetReal()), *(float(x) for x in v.GetImaginary())]
    if hasattr(v, "__iter__"):
        try:
            return [_exact(x) for x in v]
        except TypeError:
            pass
    return str(v)


def _prim_tree_signature(root) -> list:
    from pxr import Usd

    base = str(root.GetPath())
    out = []
    normal_maps = set()  # texture readers feeding a normal input: their scale and bias are checked
    for prim in Usd.PrimRange(root):
        a = prim.GetAttribute("inputs:normal")
        if a:
            normal_maps.update(str(c.GetPrimPath()) for c in a.GetConnections())
    for prim in Usd.PrimRange(root):
        rel = str(prim.GetPath())[len(base):]
        tint_ok = str(prim.GetPath()) not in normal_maps
        props = []
        for prop in prim.GetAuthoredProperties():
            if isinstance(prop, Usd.Attribute):
                conns = [str(c).replace(base, "~") for c in prop.GetConnections()]
                v = prop.Get() if prop.HasAuthoredValue() else None
                name = prop.GetName()
                vary = (name in VARYING or name.startswith("xformOp:")
                        or (tint_ok and name in ("inputs:scale", "inputs:bias")))
                props.append([name, str(prop.GetTypeName()), str(prop.GetVariability()), conns,
                              _value_class(v, None) if vary else _exact(v)])
            else:
                props.append([prop.GetName(), "rel", [str(t).replace(base, "~") for t in prop.GetTargets()]])
        meta = {k: _exact(v) for k, v in prim.GetAllAuthoredMetadata().items()
                if k not in ("specifier", "customData", "typeName", "apiSchemas")}
        out.append([rel, str(prim.GetTypeName()), [str(s) for s in prim.GetAppliedSchemas()], sorted(props), meta])
    return out


def _value_class(v, layer) -> object:
    """A value as it matters to validation: numbers by class (finite, in [0, 1]), asset paths by
    whether they resolve (and their extension), tokens and strings as they are."""
    import math

    from pxr import Sdf

    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, Sdf.AssetPath):
        return ["asset", bool(v.resolvedPath), Path(v.path).suffix]
    if isinstance(v, (int, float)):
        return ["num", math.isfinite(v), 0.0 <= v <= 1.0]
    if hasattr(v, "__iter__") and not hasattr(v, "GetReal"):
        items = list(v) if not isinstance(v, dict) else []
        if items and all(isinstance(x, str) for x in items):
            return [str(x) for x in items]
    try:
        vals = [float(x) for x in (v if not hasattr(v, "GetReal") else [v.GetReal(), *v.GetImaginary()])]
    except (TypeError, ValueError):
        return type(v).__name__ if hasattr(v, "__len__") and not isinstance(v, dict) else str(v)
    if len(vals) > 64:
        return ["array", len(vals) > 0, all(math.isfinite(x) for x in vals)]
    return ["vec", len(vals), all(math.isfinite(x) for x in vals), all(0.0 <= x <= 1.0 for x in vals)]
