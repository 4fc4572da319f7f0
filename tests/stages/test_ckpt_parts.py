"""Checkpoints in parts (stages/policy/ckpt_parts.py): packed, moved as files, unpacked to the same model."""

from __future__ import annotations

import json

import numpy as np
import pytest


def _ckpt(path):
    from safetensors.numpy import save_file

    path.mkdir()
    rng = np.random.default_rng(0)
    tensors = {"w": rng.normal(size=(64, 33)).astype(np.float32), "b": rng.normal(size=300).astype(np.float64),
               "steps": np.arange(5, dtype=np.int64)}
    save_file(tensors, str(path / "model.safetensors"))
    (path / "config.json").write_text(json.dumps({"type": "act"}))
    (path / "policy_preprocessor.json").write_text("{}")
    return tensors


@pytest.mark.parametrize("half", [True, False])
def test_a_checkpoint_packed_in_parts_unpacks_to_the_same_model(tmp_path, half):
    from safetensors.numpy import load_file

    from stages.policy.ckpt_parts import main, pack

    tensors = _ckpt(tmp_path / "ck")
    files = pack(tmp_path / "ck", tmp_path / "parts", part_mib=2 / 1024, half=half)  # 2 KiB parts
    assert files[0].name == "manifest.json" and files[1].name == "meta.tar"
    parts = [f for f in files if f.name.startswith("model.")]
    assert len(parts) >= 3 and all(f.stat().st_size <= 2048 for f in parts)
    assert main(["unpack", str(tmp_path / "parts"), str(tmp_path / "back")]) == 0
    got = load_file(tmp_path / "back" / "model.safetensors")
    assert {k: v.dtype for k, v in got.items()} == {k: v.dtype for k, v in tensors.items()}
    for k, v in tensors.items():
        np.testing.assert_allclose(got[k], v, rtol=1e-3 if half and v.dtype.kind == "f" else 0, atol=0)
    np.testing.assert_array_equal(got["steps"], tensors["steps"])
    assert (tmp_path / "back" / "config.json").read_text() == '{"type": "act"}'
    assert sorted(p.name for p in (tmp_path / "back").iterdir()) == [
        "config.json", "model.safetensors", "policy_preprocessor.json"]


def test_a_damaged_or_missing_part_fails_in_one_line_and_writes_nothing(tmp_path, capsys):
    from stages.policy.ckpt_parts import main, pack

    _ckpt(tmp_path / "ck")
    pack(tmp_path / "ck", tmp_path / "parts", part_mib=2 / 1024, half=True)
    p = tmp_path / "parts" / "model.001"
    data = bytearray(p.read_bytes())
    data[10] ^= 0xFF
    p.write_bytes(bytes(data))
    assert main(["unpack", str(tmp_path / "parts"), str(tmp_path / "back")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "model.001: damaged part" in err
    (tmp_path / "parts" / "model.002").unlink()
    assert main(["unpack", str(tmp_path / "parts"), str(tmp_path / "back")]) == 2
    assert "model.001" in capsys.readouterr().err  # the first bad part is named
    assert not (tmp_path / "back").exists() and not (tmp_path / "back.partial").exists()
    assert main(["pack", str(tmp_path / "nothing"), str(tmp_path / "p2")]) == 2
    assert "no model.safetensors" in capsys.readouterr().err


def test_unpack_never_writes_over_an_existing_folder(tmp_path, capsys):
    from stages.policy.ckpt_parts import main, pack

    _ckpt(tmp_path / "ck")
    pack(tmp_path / "ck", tmp_path / "parts")
    (tmp_path / "back").mkdir()
    assert main(["unpack", str(tmp_path / "parts"), str(tmp_path / "back")]) == 2
    assert "exists" in capsys.readouterr().err and not any((tmp_path / "back").iterdir())
