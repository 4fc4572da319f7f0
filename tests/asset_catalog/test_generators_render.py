"""Contact sheets: the render-assets command draws each category's variants with Newton's SensorCamera."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stages.render_assets import BACKGROUND, link_transforms, main, upper_limits


def test_contact_sheet_shows_the_assets(tmp_path: Path):
    assert main(["--out", str(tmp_path), "--categories", "apple,microwave", "--variants", "2", "--tile",
                 "64"]) == 0
    from PIL import Image

    apple = np.asarray(Image.open(tmp_path / "apple.png").convert("RGB")).astype(int)
    assert apple.shape == (64 + 18, 2 * 64, 3)             # one row (rigid), two variants, label strip
    for c in range(2):
        tile = apple[:64, c * 64:(c + 1) * 64]
        fg = np.abs(tile - np.array(BACKGROUND)).sum(-1) > 30
        assert 0.1 < fg.mean() < 0.9, "the apple should fill a good part of its tile"
    micro = Image.open(tmp_path / "microwave.png")
    assert micro.size == (2 * 64, 2 * (64 + 18))           # closed row + joints-at-upper-limits row
    m = np.asarray(micro.convert("RGB")).astype(int)
    assert np.abs(m[:64, :64] - m[82:146,
                                  :64]).sum(-1).mean() > 5, "the opened microwave should look different"


def test_link_transforms_follow_the_joints():
    from asset_catalog.default_catalog import generate_default_assets

    (door,) = generate_default_assets(variants_per_category=1, categories=["door"])
    model = door.model
    closed = link_transforms(model)
    opened = link_transforms(model, upper_limits(model))
    leaf = model.joints[0]
    assert np.allclose(closed["leaf"][:3, 3], opened["leaf"][:3, 3])       # the hinge does not move
    r = opened["leaf"][:3, :3]
    assert np.isclose(abs(r[0, 1]), 1.0, atol=1e-6) and leaf.upper == np.pi / 2  # turned 90 degrees about Z


def test_contact_sheets_of_a_catalog_folder(tmp_path: Path):
    """--catalog renders what the project's loaders read from the files (here the written default catalog)."""
    from PIL import Image

    from asset_catalog.default_catalog import build_default_catalog

    build_default_catalog(tmp_path / "cat", variants_per_category=1, categories=["door", "bowl"])
    assert main(["--out", str(tmp_path / "png"), "--catalog", str(tmp_path / "cat"), "--tile", "48"]) == 0
    assert Image.open(tmp_path / "png" / "door.png").size == (48, 2 * (48 + 18))
    assert Image.open(tmp_path / "png" / "bowl.png").size == (48, 48 + 18)
