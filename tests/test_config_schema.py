"""The config schema is generated from the stages' dataclasses, and bad config is caught early."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from anigs.config import deep_merge, load_scene, section

ROOT = Path(__file__).resolve().parents[1]


def test_schema_is_in_sync_with_the_code():
    res = subprocess.run([sys.executable, str(ROOT / "workflow/scripts/make_schema.py"), "--check"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def test_default_config_validates_and_every_key_has_description_and_default():
    from snakemake.utils import validate

    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    validate(cfg, str(ROOT / "workflow/schemas/config.schema.yaml"))
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())

    def walk(node, path):
        for k, v in node.get("properties", {}).items():
            assert v.get("description"), f"{path}{k} has no description"
            assert "default" in v, f"{path}{k} has no default"
            walk(v, f"{path}{k}.")

    walk(schema, "")


def test_misspelled_key_names_the_key():
    from snakemake.utils import validate

    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    cfg["update"]["stepz"] = 3
    with pytest.raises(Exception, match="stepz"):
        validate(cfg, str(ROOT / "workflow/schemas/config.schema.yaml"))


def test_scene_files_and_merging(tmp_path):
    scene = load_scene(ROOT / "config/scenes", "demo")
    assert scene["source"] == "synthetic" and scene["effects"]
    cfg = {"update": {"steps": 5, "lr_means": 1.0}, "variant_overrides": {"full": {}, "x": {"update": {"steps": 9}}}}
    scene = {"source": "synthetic", "update": {"lr_means": 2.0}}
    assert section(cfg, scene, "full", "update") == {"steps": 5, "lr_means": 2.0}
    assert section(cfg, scene, "x", "update") == {"steps": 9, "lr_means": 2.0}
    (tmp_path / "bad.yaml").write_text("source: photos\nphotos: /nonexistent/folder\n")
    with pytest.raises(FileNotFoundError, match="/nonexistent/folder"):
        load_scene(tmp_path, "bad")
    (tmp_path / "typo.yaml").write_text("source: synthetic\nefects: []\n")
    with pytest.raises(ValueError, match="efects"):
        load_scene(tmp_path, "typo")
    (tmp_path / "empty").mkdir()
    (tmp_path / "e.yaml").write_text(f"source: photos\nphotos: {tmp_path / 'empty'}\n")
    with pytest.raises(ValueError, match="no .jpg"):
        load_scene(tmp_path, "e")


def test_config_docs_are_in_sync_with_the_schema():
    res = subprocess.run([sys.executable, str(ROOT / "workflow/scripts/make_config_docs.py"), "--check"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
