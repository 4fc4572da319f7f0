"""Material rules: every class has torsional and rolling friction, and sampling keeps its draws."""

from __future__ import annotations

import numpy as np
import pytest

from asset_catalog.asset_model import ContactSpec, PhysicsMaterialSpec
from asset_catalog.materials import MATERIAL_RULES, MaterialClass, sample_physical_properties


def test_every_material_has_torsional_and_rolling_friction():
    assert set(MATERIAL_RULES) == set(MaterialClass)
    for cls, rule in MATERIAL_RULES.items():
        assert 0.001 <= rule.torsional_friction <= 0.02, cls     # [m]: about a contact patch
        assert 0.0001 <= rule.rolling_friction <= 0.005, cls     # [m]: about a deformation depth
        p = sample_physical_properties(cls, np.random.default_rng(0))
        assert (p.torsional_friction, p.rolling_friction) == (rule.torsional_friction, rule.rolling_friction)
    soft, hard = MATERIAL_RULES[MaterialClass.RUBBER], MATERIAL_RULES[MaterialClass.METAL]
    assert soft.rolling_friction > hard.rolling_friction and soft.torsional_friction > hard.torsional_friction


def test_sampled_friction_and_restitution_are_unchanged_by_the_new_fields():
    """Torsional and rolling friction take no draws: the seeded samples stay what they were."""
    rng = np.random.default_rng(7)
    p = sample_physical_properties(MaterialClass.WOOD, rng)
    ref = np.random.default_rng(7)
    dyn = ref.uniform(0.3, 0.5)
    assert p.dynamic_friction == pytest.approx(dyn) and p.restitution == pytest.approx(np.clip(ref.uniform(0.25, 0.35), 0, 1))


def test_contact_spec_overrides_only_what_it_declares():
    pm = PhysicsMaterialSpec(static_friction=0.5, dynamic_friction=0.45, restitution=0.3, density=900.0,
                             torsional_friction=0.005, rolling_friction=0.0002)
    out = ContactSpec(friction=0.9, rolling_friction=0.03).apply(pm)
    assert (out.static_friction, out.dynamic_friction, out.rolling_friction) == (0.9, 0.9, 0.03)
    assert (out.torsional_friction, out.restitution, out.density) == (0.005, 0.3, 900.0)
