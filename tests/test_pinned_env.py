"""The installed environment matches ``constraints.txt``.

Walks the dependency closure of the installed ``agentworld[test]`` distribution (requirements with
their extras and environment markers, via ``importlib.metadata``) and checks that every package in
it is pinned in ``constraints.txt`` and installed at exactly the pinned version. One failure lists
every mismatch. ``make upgrade-check`` runs this test in an unconstrained venv to list what moved.
"""

from __future__ import annotations

import importlib.metadata as md
from pathlib import Path

import pytest
from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

CONSTRAINTS = Path(__file__).resolve().parents[1] / "constraints.txt"
ROOT_DIST = "agentworld"
ROOT_EXTRAS = ("test",)


def read_constraints(path: Path = CONSTRAINTS) -> dict[str, Version]:
    """``name==version`` lines of a constraints file -> {canonical name: version}."""
    pins: dict[str, Version] = {}
    problems = []
    for lineno, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        req = Requirement(line)
        specs = list(req.specifier)
        if len(specs) != 1 or specs[0].operator != "==":
            problems.append(f"{path.name}:{lineno}: not an exact pin: {raw!r}")
            continue
        pins[canonicalize_name(req.name)] = Version(specs[0].version)
    if problems:
        raise ValueError("\n".join(problems))
    return pins


def dependency_closure(root: str = ROOT_DIST, extras: tuple[str, ...] = ROOT_EXTRAS) -> dict[str, str]:
    """Installed distributions the root needs (with extras, markers evaluated here).

    Returns {canonical name: requirer}; a required but missing distribution maps to
    ``"MISSING (required by X)"``.
    """
    env = default_environment()
    seen: dict[str, str] = {}
    queue: list[tuple[str, tuple[str, ...], str]] = [(root, extras, "-")]
    visited: set[tuple[str, tuple[str, ...]]] = set()
    while queue:
        name, want_extras, by = queue.pop()
        key = (canonicalize_name(name), tuple(sorted(want_extras)))
        if key in visited:
            continue
        visited.add(key)
        try:
            dist = md.distribution(name)
        except md.PackageNotFoundError:
            seen[key[0]] = f"MISSING (required by {by})"
            continue
        seen.setdefault(key[0], by)
        for spec in dist.requires or []:
            req = Requirement(spec)
            if req.marker is not None and not any(
                req.marker.evaluate({**env, "extra": e}) for e in (*want_extras, "")
            ):
                continue
            queue.append((req.name, tuple(req.extras), key[0]))
    return seen


def pin_mismatches(pins: dict[str, Version], closure: dict[str, str]) -> list[str]:
    """One line per package of the closure that is missing, unpinned or at another version."""
    out = []
    for name, by in sorted(closure.items()):
        if name == canonicalize_name(ROOT_DIST):
            continue
        if by.startswith("MISSING"):
            out.append(f"{name}: not installed, {by}")
            continue
        installed = Version(md.version(name))
        if name not in pins:
            out.append(f"{name}: installed {installed}, not pinned in constraints.txt (required by {by})")
        elif installed != pins[name]:
            out.append(f"{name}: installed {installed}, pinned {pins[name]}")
    return out


def test_constraints_pin_the_simulation_stack():
    pins = read_constraints()
    # newton 1.8 declares mujoco ~= 3.17; the GPU machine's wheels use the same versions.
    expected = {"newton": "1.8.0", "warp-lang": "1.19.0", "mujoco": "3.17.0", "mujoco-warp": "3.17.0"}
    assert {k: str(pins[k]) for k in expected} == expected


def test_installed_distributions_match_constraints():
    try:
        md.distribution(ROOT_DIST)
    except md.PackageNotFoundError:
        pytest.skip("agentworld is not installed (pip install -c constraints.txt -e '.[test]')")
    closure = dependency_closure()
    assert len(closure) > 50, f"dependency closure suspiciously small: {sorted(closure)}"
    bad = pin_mismatches(read_constraints(), closure)
    assert not bad, f"{len(bad)} installed distribution(s) differ from constraints.txt:\n" + "\n".join(bad)


def test_mismatches_are_listed_by_name(tmp_path):
    """A wrong pin and a dropped pin both show up, each named, in one list."""
    try:
        md.distribution(ROOT_DIST)
    except md.PackageNotFoundError:
        pytest.skip("agentworld is not installed")
    pins = read_constraints()
    pins["mujoco"] = Version("4.0.0")
    del pins["numpy"]
    bad = pin_mismatches(pins, dependency_closure())
    assert any(line.startswith("mujoco: installed 3.17.0, pinned 4.0.0") for line in bad), bad
    assert any(line.startswith("numpy: installed") and "not pinned" in line for line in bad), bad
    loose = tmp_path / "c.txt"
    loose.write_text("numpy>=1\n")
    with pytest.raises(ValueError, match="not an exact pin"):
        read_constraints(loose)
