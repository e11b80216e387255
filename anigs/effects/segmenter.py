"""Optional learned segmentation of the effects stage's photos, with local weights (``effects.segmenter``).

With ``backend: segformer`` a semantic segmenter from ``transformers`` (SegFormer fine-tuned on
ADE20K, e.g. ``nvidia/segformer-b0-finetuned-ade-512-512``, fetched once by the user into a local
folder; nothing is downloaded at run time) labels every analysed photo. Its label names (the
model config's ``id2label``) are matched by name to the stage's kinds (:data:`DEFAULT_CLASSES`,
extended or overridden by ``classes``): "tree", "plant", "palm" -> foliage, "grass", "field" ->
grass, "flower" -> flowers, "water", "sea", "river", "lake" -> water; every other label (wall,
building, painting, lamp, floor ...) is a made or still thing. Per photo this gives the
probability of each kind, ``P`` float32 [R,H,W] (R = ``len(REGIONS)``: the softmax over the model's
classes at its output resolution, summed per kind, then upsampled bilinearly to the photo).

How it combines with the weight-free cues (:func:`combine`), before the photo-to-Gaussian votes
(``anigs.effects.detect._lift``, unchanged) and the 3D geometry rules, which run as before:

- ``gate`` (default): a pixel keeps the region the weight-free cues gave it only when the
  segmenter calls it a plant (P summed over foliage, grass and flowers >= ``min_prob``; for
  water: P[water] >= ``min_prob``). What the segmenter calls a wall, a painting, a lamp or a
  building never moves, whatever its colour; the split into foliage, grass and flowers stays
  the cues' (height, colour).
- ``replace``: the pixel's region is the segmenter's most likely kind where its probability
  reaches ``min_prob`` and the fitted model covers the pixel; colour no longer decides.

``backend: none`` (the default) does not import anything and changes nothing: the stage writes the
same bytes as without this section.
"""
from __future__ import annotations

import logging
import re
import time
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import torch

from anigs.device import get_device
from anigs.effects.config import REGIONS, SegmenterConfig

log = logging.getLogger("anigs.effects")

PLANTS = ("foliage", "grass", "flowers")
SHOWN_LABELS = 40  # an error message lists at most this many of the model's labels (count)
LOGITS_NDIM = 4  # the model's logits are [batch, classes, height, width] (axes)
#: label name (a part of an id2label entry, lower case) -> kind; ADE20K's, COCO-Stuff's and Cityscapes' plant and
#: water names. Every label not listed is still.
DEFAULT_CLASSES: dict[str, str] = {
    "tree": "foliage", "trees": "foliage", "plant": "foliage", "plants": "foliage", "flora": "foliage",
    "plant life": "foliage", "potted plant": "foliage", "palm": "foliage", "palm tree": "foliage",
    "bush": "foliage", "shrub": "foliage", "hedge": "foliage", "foliage": "foliage", "vegetation": "foliage",
    "leaves": "foliage",
    "grass": "grass", "field": "grass", "lawn": "grass",
    "flower": "flowers", "flowers": "flowers",
    "water": "water", "sea": "water", "river": "water", "lake": "water", "pond": "water",
    "swimming pool": "water", "waterfall": "water",
}
WEIGHT_FILES = ("model.safetensors", "pytorch_model.bin")
HELP = ("expected a local transformers semantic-segmentation folder: config.json (with id2label), "
        "model.safetensors or pytorch_model.bin, preprocessor_config.json; get one once, online, e.g. "
        "`huggingface-cli download nvidia/segformer-b0-finetuned-ade-512-512 --local-dir weights/segformer`, "
        "and set effects.segmenter.weights to that folder (or effects.segmenter.backend: none for the "
        "weight-free cues)")


def check_weights(path: str | Path) -> Path:
    """The weights folder, or FileNotFoundError naming the path, the config key and what is expected."""
    if not path:
        raise FileNotFoundError(f"effects.segmenter.weights is not set (backend segformer); {HELP}")
    p = Path(path).expanduser()
    if not p.is_dir():
        raise FileNotFoundError(f"segmenter weights folder not found: {p} (effects.segmenter.weights); {HELP}")
    missing = [n for n in ("config.json", "preprocessor_config.json") if not (p / n).is_file()]
    if not any((p / n).is_file() for n in WEIGHT_FILES):
        missing.append(" or ".join(WEIGHT_FILES))
    if missing:
        raise FileNotFoundError(f"segmenter weights folder {p} (effects.segmenter.weights) lacks {missing}; {HELP}")
    return p


def label_names(label: str) -> list[str]:
    """The names one ``id2label`` entry stands for: the whole entry and its parts split at , ; and |
    ("plant, flora, plant life" -> plant, flora, plant life; "palm;palm;tree" -> palm, tree), lower case."""
    whole = " ".join(str(label).lower().replace("_", " ").split())
    parts = [" ".join(x.split()) for x in re.split(r"[,;|]", whole)]
    return list(dict.fromkeys([whole, *[x for x in parts if x]]))


def class_regions(id2label: Mapping, classes: Mapping[str, str] | None = None) -> dict[int, str]:
    """Class id -> kind (a name of ``REGIONS``) for the model's classes that name one.

    ``id2label``: the model config's {id: label}; ``classes``: the user's {name: kind or "still"},
    merged over :data:`DEFAULT_CLASSES`. An entry matches by its first part that names a kind."""
    table = {**DEFAULT_CLASSES, **{" ".join(str(k).lower().split()): v for k, v in dict(classes or {}).items()}}
    out: dict[int, str] = {}
    for cid, label in id2label.items():
        for name in label_names(label):
            kind = table.get(name)
            if kind is not None:
                if kind != "still":
                    out[int(cid)] = kind
                break
    return out


def region_matrix(class_region: Mapping[int, str], num_classes: int) -> np.ndarray:
    """float32 [R,C]: 1 where class c counts for kind r (R = ``len(REGIONS)``, C = ``num_classes``)."""
    m = np.zeros((len(REGIONS), num_classes), np.float32)
    for cid, kind in class_region.items():
        if 0 <= cid < num_classes:
            m[REGIONS.index(kind), cid] = 1.0
    return m


def _import_transformers():
    try:
        from transformers import AutoImageProcessor, AutoModelForSemanticSegmentation
    except Exception as exc:  # ImportError, or a broken optional dependency underneath
        raise RuntimeError(f"effects.segmenter.backend segformer needs transformers ({type(exc).__name__}: {exc}); "
                           "install the extra: pip install -c envs/constraints.txt 'anigs[ltx]'") from exc
    return AutoImageProcessor, AutoModelForSemanticSegmentation


class Segmenter:
    """A semantic segmenter loaded from a local folder; :meth:`kind_probabilities` per photo."""

    def __init__(self, cfg: SegmenterConfig):
        self.cfg = cfg
        self.path = check_weights(cfg.weights)
        self.device = get_device(cfg.device)
        Processor, Model = _import_transformers()
        from transformers.utils import logging as hf_logging

        bars = hf_logging.is_progress_bar_enabled()
        hf_logging.disable_progress_bar()  # no loading bars in the stage's log
        try:
            self.processor = Processor.from_pretrained(str(self.path), local_files_only=True)
            self.model = Model.from_pretrained(str(self.path), local_files_only=True)
        except Exception as exc:
            raise ValueError(f"segmenter weights folder {self.path} (effects.segmenter.weights) could not be loaded "
                             f"({type(exc).__name__}: {exc}); {HELP}") from exc
        finally:
            if bars:
                hf_logging.enable_progress_bar()
        for name, t in [*self.model.named_parameters(), *self.model.named_buffers()]:
            if t.is_floating_point() and not torch.isfinite(t).all():
                raise ValueError(f"segmenter weights in {self.path} (effects.segmenter.weights) hold NaN or inf "
                                 f"values (tensor {name!r}): a broken or partial download; fetch the folder again")
        self.model.to(self.device).eval().requires_grad_(False)
        id2label = dict(self.model.config.id2label or {})
        self.class_region = class_regions(id2label, cfg.classes)
        if not self.class_region:
            shown = ", ".join(str(v) for v in list(id2label.values())[:SHOWN_LABELS])
            more = " ..." if len(id2label) > SHOWN_LABELS else ""
            raise ValueError(f"segmenter {self.path}: none of its labels ({shown}{more}) "
                             "names a plant or water; map them with effects.segmenter.classes {name: foliage | grass "
                             "| flowers | water}")
        self.num_classes = int(self.model.config.num_labels)
        self.matrix = torch.from_numpy(region_matrix(self.class_region, self.num_classes)).to(self.device)

    def labels(self) -> dict[str, list[str]]:
        """Kind -> the model's labels that count for it."""
        names = {int(k): v for k, v in dict(self.model.config.id2label).items()}
        return {r: [str(names[c]) for c, k in sorted(self.class_region.items()) if k == r] for r in REGIONS}

    @torch.inference_mode()
    def kind_probabilities(self, image: np.ndarray) -> np.ndarray:
        """float32 [R,H,W]: the probability of each kind of ``REGIONS`` at every pixel of ``image``
        (RGB float [H,W,3] in [0,1]), see the module docstring."""
        h, w = image.shape[:2]
        rgb = np.clip(np.round(np.asarray(image, np.float32) * 255.0), 0, 255).astype(np.uint8)
        inputs = self.processor(images=rgb, return_tensors="pt")
        logits = self.model(pixel_values=inputs["pixel_values"].to(self.device)).logits  # [1,C,h',w']
        if logits.ndim != LOGITS_NDIM or logits.shape[1] != self.num_classes:
            raise ValueError(f"segmenter {self.path}: expected logits [1,{self.num_classes},h,w], got {tuple(logits.shape)}")
        if not torch.isfinite(logits).all():
            raise ValueError(f"segmenter {self.path} (effects.segmenter.weights) gave NaN or inf logits")
        probs = torch.einsum("rc,bchw->brhw", self.matrix, logits.float().softmax(1))
        up = torch.nn.functional.interpolate(probs, size=(h, w), mode="bilinear", align_corners=False)
        return up[0].clamp(0, 1).cpu().numpy().astype(np.float32)


def combine(masks: dict[str, np.ndarray], probs: np.ndarray, valid: np.ndarray, mode: str,
            min_prob: float) -> dict[str, dict[str, int]]:
    """Combine one photo's weight-free region ``masks`` (bool [H,W] per name of ``REGIONS``, changed
    in place) with the segmenter's ``probs`` float [R,H,W]; ``valid`` bool [H,W]: the fitted model
    covers the pixel. Returns per region the pixels removed from it and added to it."""
    if mode not in ("gate", "replace"):
        raise ValueError(f"effects.segmenter.mode must be gate or replace, got {mode!r}")
    if mode == "gate":
        plant = probs[[REGIONS.index(r) for r in PLANTS]].sum(0) >= min_prob
        water = probs[REGIONS.index("water")] >= min_prob
        new = {r: masks[r] & (water if r == "water" else plant) for r in REGIONS}
    else:
        best = probs.argmax(0)
        on = valid & (probs.max(0) >= min_prob)
        new = {r: on & (best == k) for k, r in enumerate(REGIONS)}
    counts = {"removed": {r: int((masks[r] & ~new[r]).sum()) for r in REGIONS},
              "added": {r: int((new[r] & ~masks[r]).sum()) for r in REGIONS}}
    masks.update(new)
    return counts


def apply_segmenter(maps: Sequence, regions: Sequence, cfg: SegmenterConfig, min_alpha: float) -> dict:
    """Segment every analysed photo (``maps``: :class:`~anigs.effects.regions.PhotoMaps`) and combine
    the result with its weight-free ``regions`` (:class:`~anigs.effects.regions.PhotoRegions`, changed
    in place). Returns the ``segmenter`` record of effects.json (no timings: the record is deterministic);
    ``pixels_removed`` / ``pixels_added``: per region, the share of the photos' covered pixels."""
    t0 = time.process_time()
    seg = Segmenter(cfg)
    removed, added = dict.fromkeys(REGIONS, 0), dict.fromkeys(REGIONS, 0)
    total = 0
    for p, reg in zip(maps, regions):
        probs = seg.kind_probabilities(p.image)
        valid = (p.alpha >= min_alpha) & (p.depth > 0)
        counts = combine(reg.masks, probs, valid, cfg.mode, cfg.min_prob)
        for r in REGIONS:
            removed[r] += counts["removed"][r]
            added[r] += counts["added"][r]
        total += int(valid.sum())
    cpu = time.process_time() - t0
    record = {"backend": cfg.backend, "weights": str(seg.path), "mode": cfg.mode, "min_prob": cfg.min_prob,
              "device": str(seg.device), "labels": seg.labels(), "photos": len(maps),
              "pixels_removed": {r: round(v / max(total, 1), 5) for r, v in removed.items()},
              "pixels_added": {r: round(v / max(total, 1), 5) for r, v in added.items()}}
    log.info("effects: segmenter %s (%s, mode %s) on %d photos: %.2f%% of the covered pixels left the regions, "
             "%.2f%% joined them (%.1f CPU s)", cfg.backend, seg.path, cfg.mode, len(maps),
             100 * sum(record["pixels_removed"].values()), 100 * sum(record["pixels_added"].values()), cpu)
    return record


def region_note(record: dict | None, region: str) -> str:
    """A sentence for ``region``'s reason: what the segmenter changed there ('' when it changed nothing)."""
    if not record:
        return ""
    out, gone = record["pixels_added"][region], record["pixels_removed"][region]
    if not gone and not out:
        return ""
    what = "does not call a plant or water" if record["mode"] == "gate" else "gives another kind (or none)"
    text = f" The learned segmenter took {gone:.1%} of the photos' covered pixels out of {region} (pixels it {what})"
    return text + (f" and put {out:.1%} in." if out else ".")


def note(record: dict | None) -> str:
    """One overview line for the segmenter's ``record`` ('' when none ran)."""
    if not record:
        return ""
    kinds = "; ".join(f"{r}: {', '.join(repr(x) for x in v)}" for r, v in record["labels"].items() if v)
    how = ("kept only the pixels it calls plants or water" if record["mode"] == "gate"
           else "its most likely kind is each pixel's region")
    return (f"Segmenter {record['backend']} ({record['weights']}, mode {record['mode']}): {how}; "
            f"{100 * sum(record['pixels_removed'].values()):.1f}% of the covered pixels left the regions, "
            f"{100 * sum(record['pixels_added'].values()):.1f}% joined them (labels {kinds})")
