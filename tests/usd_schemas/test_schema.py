"""The codeless AgentWorldAssetAPI schema: generated files, registration, CanApplyAPI, apply, fallbacks."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import usd_schemas
from asset_catalog.annotations import PlacementKind, RoomType
from asset_catalog.materials import MaterialClass
from usd_schemas._genschema import generate

REPO = Path(__file__).resolve().parents[2]
SCHEMA_DIR = REPO / "usd_schemas" / "agentworld"

FALLBACKS = {
    "agentworld:category": "",
    "agentworld:placement": "on_floor",
    "agentworld:roomTypes": [],
    "agentworld:materialClass": "wood",
    "agentworld:interactable": False,
    "agentworld:coOccurrence": [],
    "agentworld:sourceHash": "",
    "agentworld:pipelineVersion": "",
}


def _run(code: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter, without the plugin path that importing usd_schemas here set."""
    base = {k: v for k, v in os.environ.items() if k != "PXR_PLUGINPATH_NAME"}
    return subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120,
                          env={**base, "PYTHONPATH": str(REPO), **(env or {})})


def test_committed_generated_files_match_schema():
    gen, plug = generate(SCHEMA_DIR / "schema.usda")
    assert (SCHEMA_DIR / "generatedSchema.usda").read_text(encoding="utf-8") == gen
    assert (SCHEMA_DIR / "plugInfo.json").read_text(encoding="utf-8") == plug
    info = json.loads("".join(ln for ln in plug.splitlines(True) if not ln.startswith("#")))
    (plugin,) = info["Plugins"]
    assert plugin["Type"] == "resource" and plugin["Name"] == "agentWorld"
    entry = plugin["Info"]["Types"]["AgentWorldSchemasAssetAPI"]
    assert entry["schemaKind"] == "singleApplyAPI" and entry["schemaIdentifier"] == "AgentWorldAssetAPI"


def test_register_is_idempotent_and_defines_the_schema():
    from pxr import Plug, Usd

    usd_schemas.register()
    usd_schemas.register()
    assert Plug.Registry().GetPluginWithName("agentWorld") is not None
    assert Usd.SchemaRegistry.GetSchemaKind("AgentWorldAssetAPI") == Usd.SchemaKind.SingleApplyAPI
    prim_def = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition("AgentWorldAssetAPI")
    assert sorted(prim_def.GetPropertyNames()) == sorted(FALLBACKS)


def test_can_apply_only_to_xformables():
    from pxr import Usd, UsdGeom, UsdShade

    stage = Usd.Stage.CreateInMemory()
    xf = UsdGeom.Xform.Define(stage, "/asset").GetPrim()
    mesh = UsdGeom.Mesh.Define(stage, "/asset/mesh").GetPrim()
    mat = UsdShade.Material.Define(stage, "/mat").GetPrim()
    assert xf.CanApplyAPI("AgentWorldAssetAPI")
    assert mesh.CanApplyAPI("AgentWorldAssetAPI")
    assert not mat.CanApplyAPI("AgentWorldAssetAPI")


def test_apply_gives_fallbacks_and_allowed_tokens():
    from pxr import Sdf, Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    prim = UsdGeom.Xform.Define(stage, "/asset").GetPrim()
    assert not prim.HasAPI("AgentWorldAssetAPI")
    assert prim.ApplyAPI("AgentWorldAssetAPI")
    assert prim.HasAPI("AgentWorldAssetAPI")
    for name, fallback in FALLBACKS.items():
        attr = prim.GetAttribute(name)
        assert attr.IsValid() and not attr.HasAuthoredValue(), name
        value = attr.Get()
        assert (list(value) if hasattr(value, "__len__") and not isinstance(value, str) else value) == fallback, name
        assert attr.GetVariability() == Sdf.VariabilityUniform, name
    assert list(prim.GetAttribute("agentworld:placement").GetMetadata("allowedTokens")) == [p.value for p in PlacementKind]
    assert list(prim.GetAttribute("agentworld:materialClass").GetMetadata("allowedTokens")) == [
        m.value for m in MaterialClass]
    prim.GetAttribute("agentworld:roomTypes").Set([RoomType.KITCHEN.value])
    assert list(prim.GetAttribute("agentworld:roomTypes").Get()) == ["kitchen"]
    assert prim.RemoveAPI("AgentWorldAssetAPI") and not prim.HasAPI("AgentWorldAssetAPI")


def test_schema_documents_units_and_ranges():
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(SCHEMA_DIR / "schema.usda"))
    cls = layer.GetPrimAtPath("/AgentWorldAssetAPI")
    assert cls.documentation
    for name in FALLBACKS:
        prop = cls.properties[name]
        assert len(prop.documentation) > 40, name
        assert prop.variability == Sdf.VariabilityUniform, name
    assert "SHA-256" in cls.properties["agentworld:sourceHash"].documentation


def test_schema_in_a_fresh_process_through_the_package():
    r = _run("import usd_schemas\n"
             "from pxr import Usd, UsdGeom\n"
             "s = Usd.Stage.CreateInMemory(); p = UsdGeom.Xform.Define(s, '/a').GetPrim()\n"
             "assert p.ApplyAPI('AgentWorldAssetAPI')\n"
             "print(p.GetAttribute('agentworld:placement').Get())\n")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "on_floor"


def test_schema_in_a_fresh_process_through_pxr_pluginpath_name():
    r = _run("from pxr import Usd, UsdGeom\n"
             "s = Usd.Stage.CreateInMemory(); p = UsdGeom.Xform.Define(s, '/a').GetPrim()\n"
             "print(p.CanApplyAPI('AgentWorldAssetAPI'), p.ApplyAPI('AgentWorldAssetAPI'))\n",
             env={"PXR_PLUGINPATH_NAME": str(SCHEMA_DIR)})
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "True True"


def test_importing_usd_schemas_first_puts_both_plugins_on_the_plugin_path():
    r = _run("import os, usd_schemas\n"
             "print(os.environ['PXR_PLUGINPATH_NAME'])\n"
             "from pxr import Usd\n"
             "print(Usd.SchemaRegistry().FindAppliedAPIPrimDefinition('NewtonMaterialAPI') is not None)\n")
    assert r.returncode == 0, r.stderr
    path, newton_found = r.stdout.split()
    assert path.split(os.pathsep)[0] == str(SCHEMA_DIR) and "newton_usd_schemas" in path
    assert newton_found == "True"


def test_late_registration_warns_once_and_writes_the_same_package(tmp_path):
    """pxr's schema registry built first: register() returns False with one warning naming the fix,
    and a package written and validated in that process equals one written in a fresh process."""
    code = ("import sys, logging\n"
            "logging.basicConfig(level=logging.WARNING)\n"
            "from pxr import Usd\n"
            "Usd.SchemaRegistry()\n"
            "import usd_schemas\n"
            "print(usd_schemas.register(), usd_schemas.register())\n"
            "sys.path.insert(0, 'tests/usd_schemas')\n"
            "import usd_test_models as M\n"
            "from pathlib import Path\n"
            "pkg = usd_schemas.write_asset_package(M.cabinet_model(), Path(sys.argv[1]), pipeline_version='0.1.0')\n"
            "print(usd_schemas.validate_package(pkg.root_path).ok)\n")
    late = subprocess.run([sys.executable, "-c", code, str(tmp_path / "late")], cwd=REPO, capture_output=True,
                          text=True, timeout=120, env={**{k: v for k, v in os.environ.items()
                                                          if k != "PXR_PLUGINPATH_NAME"}, "PYTHONPATH": str(REPO)})
    assert late.returncode == 0, late.stderr
    assert late.stdout.split() == ["False", "False", "True"]
    assert late.stderr.count("is not in USD's schema registry") == 1
    assert "PXR_PLUGINPATH_NAME=" in late.stderr
    import usd_test_models as M

    early = usd_schemas.write_asset_package(M.cabinet_model(), tmp_path / "early", pipeline_version="0.1.0")
    for name in ("cabinet_01.usda", "cabinet_01_payload.usdc"):
        from pxr import Sdf

        a = Sdf.Layer.FindOrOpen(str(tmp_path / "late" / name)).ExportToString()
        b = Sdf.Layer.FindOrOpen(str(early.root_path.parent / name)).ExportToString()
        assert a == b


def test_generate_rejects_non_codeless_schema(tmp_path):
    (tmp_path / "schema.usda").write_text('#usda 1.0\nover "GLOBAL" (customData = {string libraryName = "x"}) {}\n')
    with pytest.raises(ValueError, match="codeless"):
        generate(tmp_path / "schema.usda")
