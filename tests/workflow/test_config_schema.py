"""The config schema is generated from the stages' dataclasses, and bad config is caught early."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from anigs.config import load_scene, section

ROOT = Path(__file__).resolve().parents[2]


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
    cfg.update(seed=3, device="cpu")
    handed = {"seed": 3, "device": "cpu"}
    assert section(cfg, scene, "full", "update", _schema()) == {"steps": 5, "lr_means": 2.0, **handed}
    assert section(cfg, scene, "x", "update", _schema()) == {"steps": 9, "lr_means": 2.0, **handed}
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


def test_photo_scene_folder_from_an_environment_variable(tmp_path, monkeypatch):
    """config/scenes/photos.yaml names its folder as ${ANIGS_PHOTOS}: expanded when the scene is
    loaded, and an unset or empty variable fails naming it and the scene file."""
    monkeypatch.delenv("ANIGS_PHOTOS", raising=False)
    with pytest.raises(ValueError, match=r"ANIGS_PHOTOS.*not set") as err:
        load_scene(ROOT / "config/scenes", "photos", _schema())
    assert "photos.yaml" in str(err.value)
    monkeypatch.setenv("ANIGS_PHOTOS", "")
    with pytest.raises(ValueError, match=r"ANIGS_PHOTOS.*empty"):
        load_scene(ROOT / "config/scenes", "photos")
    photos = tmp_path / "shots"
    photos.mkdir()
    (photos / "a.png").write_bytes(b"")
    monkeypatch.setenv("ANIGS_PHOTOS", str(photos))
    scene = load_scene(ROOT / "config/scenes", "photos", _schema())
    assert scene["source"] == "photos" and scene["photos"] == str(photos)
    # inside a longer path too; a missing folder names the reference it came from
    (tmp_path / "sub.yaml").write_text("source: photos\nphotos: ${ANIGS_PHOTOS}/../missing\n")
    with pytest.raises(FileNotFoundError, match=r"missing.*\$\{ANIGS_PHOTOS\}"):
        load_scene(tmp_path, "sub")


def test_config_docs_are_in_sync_with_the_schema():
    res = subprocess.run([sys.executable, str(ROOT / "workflow/scripts/make_config_docs.py"), "--check"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def _schema() -> dict:
    return yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())


@pytest.mark.parametrize("section, text, match", [
    ("static", "static: {iteratons: 5}", r"typo\.yaml.*iteratons"),
    ("masks", "masks: {vegetation: {exgr_thresh: 0.1}}", r"masks\.vegetation.*exgr_thresh"),
    ("masks", "masks: {labels: {treshold: 0.4}}", r"typo\.yaml.*masks\.labels.*treshold"),
    ("eval", "eval: {multiview_fit: {densify: {evry: 5}}}", r"typo\.yaml.*eval\.multiview_fit\.densify.*evry"),
    ("update", "update: {steps: many}", r"update\.steps"),
])
def test_a_bad_key_in_a_scene_file_names_the_file_and_the_whole_key(tmp_path, section, text, match):
    """A typo or a wrong type in a stage section of a scene file, at any depth of its nested sections."""
    (tmp_path / "typo.yaml").write_text(f"source: synthetic\n{text}\n")
    with pytest.raises(ValueError, match=match) as exc:
        load_scene(tmp_path, "typo", _schema())
    assert section in str(exc.value)


def test_a_good_stage_section_of_a_scene_file_is_kept(tmp_path):
    (tmp_path / "ok.yaml").write_text("source: synthetic\nstatic: {iterations: 5}\n")
    assert load_scene(tmp_path, "ok", _schema())["static"] == {"iterations": 5}


def test_scene_file_typo_fails_when_the_workflow_is_parsed(tmp_path):
    """A dry run stops before any job, naming the key and the scene file."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "typo.yaml").write_text("source: synthetic\nstatic: {iteratons: 5}\n")
    exe = Path(sys.executable).with_name("snakemake")
    res = subprocess.run([str(exe), "-n", "--cores", "1", "--config", f"scene_dir={scenes}", "scenes=[typo]",
                          f"results={tmp_path / 'results'}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode != 0
    out = res.stdout + res.stderr
    assert "iteratons" in out and "typo.yaml" in out, out[-3000:]
    assert not (tmp_path / "results").exists()


def test_variant_override_typo_names_the_variant():
    from anigs.config import check_sections

    with pytest.raises(ValueError, match=r"variant_overrides\.x.*update.*stepz"):
        check_sections({"update": {"stepz": 3}}, _schema(), "config: variant_overrides.x")


def test_the_stage_list_is_written_once():
    """The CLI, the config sections, the sweep and the schema all derive from anigs.stages.STAGES."""
    from anigs.cli import commands
    from anigs.config import STAGE_SECTIONS
    from anigs.stages import STAGES, get
    from anigs.reports.tradeoff import SCENE_STAGE_ORDER, VARIANT_SECTIONS

    from anigs import contract

    names = [s.name for s in STAGES]
    assert STAGE_SECTIONS == tuple(s.name for s in STAGES if s.section)
    assert set(VARIANT_SECTIONS) | set(SCENE_STAGE_ORDER) == set(STAGE_SECTIONS)
    assert [c for c in commands() if c in names] == [s.name for s in STAGES if s.command]
    schema = _schema()["properties"]
    assert all(name in schema for name in STAGE_SECTIONS)
    for s in STAGES:  # one name: module, config class, rule
        mod = s.load()
        if s.command:  # its own command line, or the default one (anigs.stages.command.stage_main): Inputs + run
            own = callable(getattr(mod, "main", None)) and callable(getattr(mod, "add_arguments", None))
            assert own or (callable(mod.run) and issubclass(mod.Inputs, contract.Inputs)), s.name
        if s.section:
            assert mod.Config is s.config_class()
    rules = "\n".join(p.read_text() for p in (ROOT / "workflow/rules").glob("*.smk"))
    for s in STAGES:
        if s.name not in ("capture", "animate"):  # capture: one rule per source; animate: a target
            assert f"\nrule {s.name}:" in rules or f"\ncheckpoint {s.name}:" in rules, s.name
    with pytest.raises(KeyError, match="now called 'final'"):
        get("render")


def test_old_command_names_fail_naming_the_new_one(capsys):
    from anigs.cli import main

    with pytest.raises(SystemExit):
        main(["render-clip", "--help"])
    assert "now called 'render_clip'" in capsys.readouterr().err


def test_the_runs_device_reaches_every_stage_and_a_section_may_not_set_its_own(tmp_path):
    """The workflow's one device (and seed) reaches SfM and the fit alike; a scene file's stage section that
    sets its own fails when the workflow is parsed, naming the top-level key; so does the workflow config's."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "dev.yaml").write_text("source: synthetic\nsynthetic: {}\n")
    (scenes / "old.yaml").write_text("source: synthetic\nsynthetic: {}\nstatic: {device: cpu}\n")
    exe = Path(sys.executable).with_name("snakemake")

    def dry(scene: str, *config: str) -> subprocess.CompletedProcess:
        return subprocess.run([str(exe), "-n", "-p", "--cores", "1", "--config", f"scene_dir={scenes}",
                               f"scenes=[{scene}]", f"results={tmp_path / 'results'}", *config, "--",
                               f"{tmp_path}/results/{scene}/static/canonical.ply"],
                              cwd=ROOT, capture_output=True, text=True, timeout=300)

    res = dry("dev", "device=cpu", "seed=4")
    assert res.returncode == 0, res.stderr[-3000:]
    for stage in ("sfm", "static"):
        cmd = next(line for line in res.stdout.splitlines() if f" {stage} --images" in line)
        assert '"device": "cpu"' in cmd and '"seed": 4' in cmd, cmd
    res = dry("old")
    assert res.returncode != 0 and "static.device is now device, set once at the top level of the workflow config" \
        in res.stdout + res.stderr, (res.stdout + res.stderr)[-3000:]
    res = dry("dev", "static={seed: 3}")
    assert res.returncode != 0 and "static.seed is now seed" in res.stdout + res.stderr, (res.stdout + res.stderr)[-3000:]


def test_photo_scenes_pair_the_sfm_cameras_with_the_undistorted_images(tmp_path):
    """sfm/cameras.json describes the undistorted sfm/images; capture/images are the distorted
    originals. Every job that reads the cameras with images must read sfm/images."""
    import cv2
    import numpy as np

    photos = tmp_path / "photos"
    photos.mkdir()
    for i in range(3):
        cv2.imwrite(str(photos / f"p{i}.png"), np.full((8, 8, 3), 40 * i, np.uint8))
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "ph.yaml").write_text(f"source: photos\nphotos: {photos}\neffects: [foliage_sway]\n")
    exe = Path(sys.executable).with_name("snakemake")
    res = subprocess.run([str(exe), "-n", "-p", "--cores", "1", "--config", f"scene_dir={scenes}", "scenes=[ph]",
                          f"results={tmp_path / 'results'}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    cmds = [line for line in res.stdout.splitlines() if "--cameras" in line and "--images" in line]
    def stage(cmd: str) -> str:  # the word after `anigs [--threads N]`
        words = cmd.split("anigs ", 1)[1].split()
        return words[2] if words[0] == "--threads" else words[0]

    assert {stage(c) for c in cmds} >= {"effects", "masks", "static"}
    for c in cmds:
        images = c.split("--images ", 1)[1].split()[0]
        assert images.endswith("/sfm/images"), c
    # the eval stage takes the sfm stage's folder: its cameras with its own (undistorted) images
    evals = [line for line in res.stdout.splitlines() if "--part model" in line]
    assert evals and all(c.split("--sfm ", 1)[1].split()[0].endswith("/ph/sfm") and "--images" not in c
                         for c in evals), evals
    # the region of interest is computed once, by the effects stage, and the views stage takes it
    views = next(line for line in res.stdout.splitlines() if " views --canonical" in line)
    assert "--effects " in views and views.split("--effects ", 1)[1].split()[0].endswith("/ph/effects"), views
    assert "--labels" not in views, views
    # ... and reads the photos only to judge its views against them (views.min_motion_sharpness)
    assert views.split("--images ", 1)[1].split()[0].endswith("/ph/sfm/images"), views


def test_one_scene_background_reaches_every_rendering_stage(tmp_path):
    """A scene's `background` sets the sky colour of every section that renders (the schema's x-handed:
    static, views, masks, render_clip, update, final, view, fvd_gt, eval's multiview fit, the baselines)
    and of the synthetic capture (tests/workflow/test_handed.py: every handed path)."""
    schema = _schema()
    (tmp_path / "s.yaml").write_text("source: synthetic\nsynthetic: {}\nbackground: [0.1, 0.2, 0.3]\n")
    scene = load_scene(tmp_path, "s", schema)
    cfg = {"seed": 0, "device": "auto", "variant_overrides": {"full": {}}}
    for name in ("static", "masks", "render_clip", "update", "final", "view", "views", "fvd_gt"):
        assert section(cfg, scene, "full", name, schema)["background"] == [0.1, 0.2, 0.3], name
    assert section(cfg, scene, "full", "eval", schema)["multiview_fit"]["background"] == [0.1, 0.2, 0.3]
    assert scene["synthetic"]["capture"]["background"] == [0.1, 0.2, 0.3]
    (tmp_path / "bad.yaml").write_text("source: synthetic\nbackground: [0.1, 0.2]\n")
    with pytest.raises(ValueError, match="background"):
        load_scene(tmp_path, "bad", schema)


def test_workflow_scenes_checks_the_scenes_and_variants_the_config_runs(tmp_path):
    """anigs.config.workflow_scenes (common.smk at parse time): scene files from the scene folder
    (relative: the working directory's, else the workflow's), the variant overrides' sections, the
    variants the config runs defined, and no scene name with the sweep's marker."""
    from anigs.config import workflow_scenes

    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    scenes = workflow_scenes(cfg, _schema(), ROOT, "--")
    assert list(scenes) == list(cfg["scenes"]) and scenes["demo"]["source"] == "synthetic"
    with pytest.raises(ValueError, match="variant 'nope' is not defined under variant_overrides"):
        workflow_scenes(dict(cfg, variants=["full", "nope"]), _schema(), ROOT, "--")
    with pytest.raises((KeyError, ValueError), match="variant_overrides.x"):
        workflow_scenes(dict(cfg, variant_overrides={**cfg["variant_overrides"], "x": {"update": {"stepz": 3}}}),
                        _schema(), ROOT, "--")
    (tmp_path / "a--b.yaml").write_text((ROOT / "config/scenes/demo.yaml").read_text())
    with pytest.raises(ValueError, match="may not contain '--'"):
        workflow_scenes(dict(cfg, scenes=["a--b"], scene_dir=str(tmp_path)), _schema(), ROOT, "--")
