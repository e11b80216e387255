"""Optional learned segmentation (anigs.effects.segmenter) on random-weight SegFormer folders saved to
disk and loaded back: the real code path (transformers' loader, the image processor, the model, the
softmax per kind, the photo-to-Gaussian votes and the geometry rules) on a small hand-built scene.

Where a test needs the segmenter to say something definite, the model's output is forced: the
classifier's bias (one class everywhere), or a hook on its decode head that sets the logits from
the colour of the input it was given (an oracle standing in for trained weights).
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from tests.effects.test_effects import bush_with_a_blossom

pytest.importorskip("transformers", reason="transformers not installed (extra: anigs[ltx])")

from anigs.effects import REGIONS, EffectsConfig, detect_effects  # noqa: E402
from anigs.effects.segmenter import Segmenter, check_weights, class_regions, combine  # noqa: E402
from anigs.effects.segmenter_tiny import save_random_segformer  # noqa: E402

pytestmark = pytest.mark.usefixtures("one_thread")
LABELS = ["wall", "tree", "flower", "grass", "painting, picture", "water", "lamp"]
SIZE = (120, 160)  # the processor's input (height, width): logits of 30 x 40


@pytest.fixture(scope="module")
def weights(tmp_path_factory):
    return save_random_segformer(tmp_path_factory.mktemp("segformer"), LABELS, SIZE)


@pytest.fixture(scope="module")
def bush():
    """tests/effects/test_effects.py's bush with a red blossom; labels 0 floor, 1 leaves, 2 blossom."""
    return bush_with_a_blossom()


def _cfg(weights=None, **seg) -> EffectsConfig:
    section = {"backend": "segformer", "weights": str(weights), "device": "cpu", **seg} if weights else {}
    return EffectsConfig.from_dict({"segmenter": section} if section else {})


def _share(res, labels, part: int, region: str) -> float:
    """Share of the Gaussians labelled ``part`` whose region is ``region``."""
    return float((res.region_of[labels == part] == REGIONS.index(region)).mean())


def _forced(monkeypatch, by_colour: dict[str, str]):
    """Make every Segmenter's decode head answer by the colour of the input pixels it was given: red,
    green and other pixels get the label ``by_colour`` names (logit 8, the other classes 0)."""
    real_init = Segmenter.__init__

    def init(self, cfg):
        real_init(self, cfg)
        seen = {}
        mean = torch.tensor(self.processor.image_mean).view(1, 3, 1, 1)
        std = torch.tensor(self.processor.image_std).view(1, 3, 1, 1)
        self.model.register_forward_pre_hook(
            lambda mod, args, kwargs: seen.update(x=kwargs["pixel_values"] * std + mean), with_kwargs=True)

        def head(mod, args, out):
            rgb = torch.nn.functional.adaptive_avg_pool2d(seen["x"], out.shape[-2:])[0]
            r, g = rgb[0], rgb[1]
            kind = {"red": (r > 0.4) & (r > 2 * g), "green": (g > r) & (g > rgb[2])}
            kind["other"] = ~(kind["red"] | kind["green"])
            logits = torch.zeros_like(out)
            for colour, label in by_colour.items():
                logits[0, LABELS.index(label)][kind[colour]] = 8.0
            return logits

        self.model.decode_head.register_forward_hook(head)

    monkeypatch.setattr(Segmenter, "__init__", init)


def test_label_names_map_to_kinds():
    ade = {0: "wall", 1: "building, edifice", 4: "tree", 9: "grass", 17: "plant, flora, plant life",
           22: "painting, picture", 29: "field", 36: "lamp", 66: "flower", 72: "palm, palm tree", 125: "pot, flowerpot",
           21: "water", 26: "sea", 60: "river", 8: "windowpane;window"}
    assert class_regions(ade) == {4: "foliage", 9: "grass", 17: "foliage", 29: "grass", 66: "flowers",
                                  72: "foliage", 21: "water", 26: "water", 60: "water"}
    # the user's names extend and override the built-in ones
    assert class_regions(ade, {"field": "still", "Palm": "flowers", "pot": "foliage"}) == {
        4: "foliage", 9: "grass", 17: "foliage", 66: "flowers", 72: "flowers", 125: "foliage", 21: "water",
        26: "water", 60: "water"}


def test_combine_gates_or_replaces_the_masks():
    h, w = 4, 5
    masks = {r: np.zeros((h, w), bool) for r in REGIONS}
    masks["flowers"][0] = True   # colour says blossom: a red lamp in row 0, a real blossom in row 1
    masks["flowers"][1] = True
    masks["foliage"][2] = True
    probs = np.zeros((len(REGIONS), h, w), np.float32)
    probs[REGIONS.index("flowers"), 1] = 0.7   # the segmenter: row 1 a flower, row 2 a tree, rows 0 and 3 made things
    probs[REGIONS.index("foliage"), 2] = 0.3
    probs[REGIONS.index("grass"), 2] = 0.3
    probs[REGIONS.index("grass"), 3] = 0.9
    gated = {k: v.copy() for k, v in masks.items()}
    counts = combine(gated, probs, np.ones((h, w), bool), "gate", 0.5)
    assert counts["removed"] == {"foliage": 0, "grass": 0, "flowers": w, "water": 0}
    assert sum(counts["added"].values()) == 0
    assert not gated["flowers"][0].any() and gated["flowers"][1].all() and gated["foliage"][2].all()
    assert not gated["grass"].any()  # the gate never adds a pixel
    valid = np.ones((h, w), bool)
    valid[3, 0] = False
    replaced = {k: v.copy() for k, v in masks.items()}
    counts = combine(replaced, probs, valid, "replace", 0.5)
    assert not replaced["flowers"][0].any() and replaced["flowers"][1].all()
    assert not replaced["foliage"].any()  # 0.3 each: no kind reaches 0.5
    assert replaced["grass"][3].sum() == w - 1 and not replaced["grass"][3, 0]
    assert counts == {"removed": {"foliage": w, "grass": 0, "flowers": w, "water": 0},
                      "added": {"foliage": 0, "grass": w - 1, "flowers": 0, "water": 0}}


def test_missing_or_broken_weights_are_named(tmp_path, bush):
    g, cams, imgs = bush
    with pytest.raises(FileNotFoundError, match=r"effects.segmenter.weights is not set.*huggingface-cli download"):
        check_weights("")
    missing = tmp_path / "no_such_folder"
    with pytest.raises(FileNotFoundError, match=rf"{missing}.*effects.segmenter.weights.*huggingface-cli download "
                                                r"nvidia/segformer-b0-finetuned-ade-512-512"):
        detect_effects(imgs, cams, g, _cfg(missing))
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "config.json").write_text("{}")
    with pytest.raises(FileNotFoundError, match=r"lacks \['preprocessor_config.json', 'model.safetensors or "
                                                r"pytorch_model.bin'\]"):
        check_weights(tmp_path / "half")
    for bad, match in (({"backend": "sam"}, "backend must be one of"), ({"mode": "vote"}, "mode must be one of"),
                       ({"classes": {"tree": "trees"}}, "map to no kind"), ({"min_prob": 0}, "min_prob"),
                       ({"weight": "x"}, r"unknown keys \['weight'\]")):
        with pytest.raises(ValueError, match=match):
            EffectsConfig.from_dict({"segmenter": bad})


def test_nan_weights_and_labels_naming_no_plant_are_refused(tmp_path):
    from transformers import SegformerForSemanticSegmentation

    path = save_random_segformer(tmp_path / "nan", LABELS, SIZE)
    model = SegformerForSemanticSegmentation.from_pretrained(path)
    with torch.no_grad():
        model.decode_head.classifier.weight[0, 0] = float("nan")
    model.save_pretrained(path)
    with pytest.raises(ValueError, match=rf"{path}.*NaN or inf.*decode_head.classifier.weight"):
        Segmenter(_cfg(path).segmenter)
    other = save_random_segformer(tmp_path / "street", ["road", "car", "sky"], SIZE)
    with pytest.raises(ValueError, match=r"none of its labels \(road, car, sky\).*effects.segmenter.classes"):
        Segmenter(_cfg(other).segmenter)
    assert Segmenter(_cfg(other, classes={"car": "water"}).segmenter).class_region == {1: "water"}


def _biased(tmp_path, label: str):
    """The tiny model with its classifier answering ``label`` at every pixel (weights 0, bias 10)."""
    from transformers import SegformerForSemanticSegmentation

    path = save_random_segformer(tmp_path / label, LABELS, SIZE)
    model = SegformerForSemanticSegmentation.from_pretrained(path)
    with torch.no_grad():
        model.decode_head.classifier.weight.zero_()
        model.decode_head.classifier.bias.zero_()
        model.decode_head.classifier.bias[LABELS.index(label)] = 10.0
    model.save_pretrained(path)
    return path


def test_one_class_everywhere_gates_the_colour_cues(tmp_path, bush):
    """A segmenter that sees a wall everywhere keeps everything still; one that sees a tree everywhere
    lets the weight-free regions through unchanged (the gate only removes)."""
    g, cams, imgs = bush
    base = detect_effects(imgs, cams, g, _cfg())
    assert base.segmenter is None and "segmenter" not in base.to_json() and "segmenter" not in base.cfg.to_dict()
    wall = detect_effects(imgs, cams, g, _cfg(_biased(tmp_path, "wall")))
    assert wall.detected == [] and (wall.region_of == -1).all()
    assert wall.segmenter["pixels_removed"]["foliage"] > 0.1 and wall.segmenter["labels"]["foliage"] == ["tree"]
    assert "learned segmenter took" in wall.effects["foliage_sway"].reason
    tree = detect_effects(imgs, cams, g, _cfg(_biased(tmp_path, "tree")))
    assert tree.detected == base.detected and np.array_equal(tree.region_of, base.region_of)
    assert sum(tree.segmenter["pixels_removed"].values()) == 0 and tree.to_json()["config"]["segmenter"]["mode"] == "gate"


def test_pixels_the_segmenter_calls_a_lamp_never_move(monkeypatch, tmp_path, bush):
    """Gate: the red blossom is a flower by colour (weight-free); a segmenter that calls the red pixels a
    lamp (and the green ones a tree) keeps it still, and the leaves still sway."""
    g, cams, imgs = bush
    labels = g.extras["label"].numpy()
    base = detect_effects(imgs, cams, g, _cfg())
    assert _share(base, labels, 2, "flowers") >= 0.6 and _share(base, labels, 1, "foliage") >= 0.7
    _forced(monkeypatch, {"red": "lamp", "green": "tree", "other": "wall"})
    res = detect_effects(imgs, cams, g, _cfg(save_random_segformer(tmp_path / "m", LABELS, SIZE)))
    print(f"gate: blossom in flowers {_share(res, labels, 2, 'flowers'):.3f}, moving "
          f"{float((res.region_of[labels == 2] >= 0).mean()):.3f}; leaves in foliage {_share(res, labels, 1, 'foliage'):.3f}")
    assert float((res.region_of[labels == 2] >= 0).mean()) <= 0.05
    assert _share(res, labels, 1, "foliage") >= 0.7 and not res.effects["flower_bob"].detected
    assert (res.region_of[labels == 0] == -1).mean() >= 0.99


@pytest.mark.parametrize("red, region", [("flower", "flowers"), ("tree", "foliage")])
def test_replace_takes_the_segmenters_kind(monkeypatch, tmp_path, bush, red, region):
    """Replace: the red blossom takes the kind the segmenter gives its pixels (a flower bobs, a tree's
    red leaves sway), the green leaves foliage, the floor nothing."""
    g, cams, imgs = bush
    labels = g.extras["label"].numpy()
    _forced(monkeypatch, {"red": red, "green": "tree", "other": "wall"})
    res = detect_effects(imgs, cams, g, _cfg(save_random_segformer(tmp_path / "m", LABELS, SIZE), mode="replace"))
    other = "foliage" if region == "flowers" else "flowers"
    print(f"replace, red = {red}: blossom in {region} {_share(res, labels, 2, region):.3f}, in {other} "
          f"{_share(res, labels, 2, other):.3f}; leaves in foliage {_share(res, labels, 1, 'foliage'):.3f}")
    assert _share(res, labels, 2, region) >= 0.6 and _share(res, labels, 2, other) <= 0.1
    assert _share(res, labels, 1, "foliage") >= 0.7 and _share(res, labels, 1, "flowers") <= 0.1
    assert (res.region_of[labels == 0] == -1).mean() >= 0.99
    assert res.segmenter["mode"] == "replace"
    if red == "tree":  # the blossom's pixels left flowers for foliage; no label of the oracle makes flowers
        assert res.segmenter["pixels_removed"]["flowers"] > 0 and res.segmenter["pixels_added"]["flowers"] == 0


def test_stage_backend_none_writes_the_same_bytes_and_segformer_records_itself(tmp_path, bush, weights):
    """`anigs effects`: a segmenter section with backend none changes no byte of the stage's files; the
    segformer backend runs from the CLI and says so in effects.json and on the overview."""
    from anigs.cameras import save_cameras
    from anigs.cli import main
    from anigs.images import write_rgb_png

    g, cams, imgs = bush
    g.save_ply(tmp_path / "canonical.ply")
    save_cameras(tmp_path / "cameras.json", cams)
    for cam, img in zip(cams, imgs):
        write_rgb_png(tmp_path / "images" / cam.name, img)
    base = ["effects", "--canonical", str(tmp_path / "canonical.ply"), "--cameras", str(tmp_path / "cameras.json"),
            "--images", str(tmp_path / "images")]
    none = json.dumps({"segmenter": {"backend": "none", "weights": str(tmp_path / "absent"), "mode": "replace"}})
    seg = json.dumps({"segmenter": {"backend": "segformer", "weights": str(weights), "device": "cpu"}})
    for name, params in (("default", "{}"), ("none", none), ("segformer", seg)):
        assert main(base + ["--out", str(tmp_path / name), "--params", params]) == 0
    files = ("effects.json", "regions.npy", "dynamic.npy", "overview.png")
    for f in files:
        assert (tmp_path / "default" / f).read_bytes() == (tmp_path / "none" / f).read_bytes(), f
    doc = json.loads((tmp_path / "segformer" / "effects.json").read_text())
    assert doc["segmenter"]["labels"] == {"foliage": ["tree"], "grass": ["grass"], "flowers": ["flower"],
                                          "water": ["water"]}
    assert doc["segmenter"]["weights"] == str(weights) and doc["config"]["segmenter"]["backend"] == "segformer"
    again = tmp_path / "again"
    assert main(base + ["--out", str(again), "--params", seg]) == 0
    for f in files:  # deterministic on CPU
        assert (tmp_path / "segformer" / f).read_bytes() == (again / f).read_bytes(), f
