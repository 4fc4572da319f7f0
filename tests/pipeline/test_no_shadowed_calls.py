"""A function's parameter that takes the name of a module-level function or import and is then
called in the body calls the argument (a float, a bool), not the function: session 14's split of
``table_tasks`` left ``table_rig.open_hand(..., hook=...)`` calling its bool ``hook`` and
``table_drawer._back_off(..., open_hand=...)`` calling its float ``open_hand``, which broke every
drawer-opening episode of the hands (found by a GPU-host record-table run; only slow tests ran them)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("pipeline", "usd_schemas", "asset_catalog", "stages", "jobs")


def _module_names(tree: ast.Module) -> set[str]:
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return names


def shadowed_calls(source: str, path: str = "<src>") -> list[str]:
    """``path:line: f(... x ...) calls its parameter x, which shadows the module's x`` for each case."""
    tree = ast.parse(source)
    top = _module_names(tree)
    out = []
    for fn in ast.walk(tree):
        if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        a = fn.args
        params = {p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)} & top
        if not params:
            continue
        for node in ast.walk(fn):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in params:
                out.append(f"{path}:{node.lineno}: {fn.name}() calls its parameter {node.func.id!r}, "
                           f"which shadows the module's {node.func.id!r}")
    return out


def test_the_check_finds_a_parameter_called_in_place_of_the_function():
    src = ("def hook(x):\n    return x\n\n"
           "def open_hand(d, *, hook=False):\n    hook(d) if hook else None\n")
    assert len(shadowed_calls(src)) == 1
    assert shadowed_calls(src.replace("hook=False", "hooked=False").replace("if hook", "if hooked")) == []


def test_no_function_calls_a_parameter_that_shadows_a_module_function():
    problems = []
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            problems += shadowed_calls(f.read_text(), str(f.relative_to(ROOT)))
    assert problems == []
