"""Cache keys: what changes them and what does not."""

from __future__ import annotations

import sys

import pytest

from pipeline._src import cache


def _key(**over):
    base = dict(fn="m:f", params_type="m:P", params_json='{"a":1}', seed=1, input_shas=["x"], code="c",
                dep_keys=["d"])
    return cache.item_key(**{**base, **over})


def test_item_key_depends_on_every_input():
    k = _key()
    assert k == _key() and len(k) == 64
    for change in (dict(fn="m:g"), dict(params_type="m:Q"), dict(params_json='{"a":2}'), dict(seed=2),
                   dict(input_shas=["y"]), dict(code="c2"), dict(dep_keys=["e"]), dict(input_shas=[])):
        assert _key(**change) != k, change


def test_canonical_json_is_order_independent():
    assert cache.canonical_json({"b": 1, "a": [1, {"d": 2, "c": 3}]}) == '{"a":[1,{"c":3,"d":2}],"b":1}'
    with pytest.raises(ValueError):
        cache.canonical_json({"x": float("nan")})


@pytest.fixture
def pkg(tmp_path, monkeypatch):
    """A package ``cachepkg`` with a stage module declaring CODE_DEPS on a helper package."""
    root = tmp_path / "src"
    (root / "cachepkg" / "helpers").mkdir(parents=True)
    (root / "cachepkg" / "__init__.py").write_text("")
    (root / "cachepkg" / "helpers" / "__init__.py").write_text("")
    (root / "cachepkg" / "helpers" / "geo.py").write_text("def area(r):\n    return 3.14 * r * r\n")
    (root / "cachepkg" / "other.py").write_text("X = 1\n")
    (root / "cachepkg" / "stage.py").write_text(
        'CODE_DEPS = ("cachepkg.helpers",)\n\ndef run(params, ctx):\n    return None\n')
    (root / "cachepkg" / "plain.py").write_text("def run(params, ctx):\n    return None\n")
    monkeypatch.syspath_prepend(str(root))
    yield root
    for name in [m for m in sys.modules if m.startswith("cachepkg")]:
        del sys.modules[name]


def _fresh(fn: str) -> str:
    cache.code_version.cache_clear()
    cache.module_source_sha.cache_clear()
    return cache.code_version(fn)


def test_code_version_follows_module_and_declared_deps(pkg):
    v = _fresh("cachepkg.stage:run")
    assert v.startswith(cache.package_version() + "+") and v.count("+") >= 2
    assert "cachepkg.stage" not in sys.modules                      # read, never imported
    (pkg / "cachepkg" / "other.py").write_text("X = 2\n")           # not a dependency
    assert _fresh("cachepkg.stage:run") == v
    (pkg / "cachepkg" / "helpers" / "geo.py").write_text("def area(r):\n    return 3.1416 * r * r\n")
    v2 = _fresh("cachepkg.stage:run")
    assert v2 != v
    (pkg / "cachepkg" / "stage.py").write_text(
        'CODE_DEPS = ("cachepkg.helpers",)\n\ndef run(params, ctx):\n    return None  # edited\n')
    assert _fresh("cachepkg.stage:run") != v2
    plain = _fresh("cachepkg.plain:run")
    (pkg / "cachepkg" / "helpers" / "geo.py").write_text("def area(r):\n    return 0\n")
    assert _fresh("cachepkg.plain:run") == plain                    # no CODE_DEPS: module only


def test_bad_code_deps_and_missing_module(pkg):
    (pkg / "cachepkg" / "bad.py").write_text("CODE_DEPS = 'cachepkg.helpers'\n")
    with pytest.raises(ValueError, match="CODE_DEPS must be a tuple"):
        _fresh("cachepkg.bad:run")
    with pytest.raises(LookupError):
        _fresh("cachepkg.absent:run")
