"""Which effects a scene contains and where: :func:`detect_effects` and its result.

Pipeline (no downloaded weights):

1. ``photos``: a few capture photos (``photos.max_photos``, evenly spaced, downscaled to ``max_side``);
2. ``cues``: 3D cues of the fitted model: up, ground plane, per-Gaussian surface variation and
   ``|normal . up|`` (:func:`~anigs.effects.geometry.local_shape`), multi-view colour spread, and
   per photo the model's depth/alpha and the cue maps rendered at its camera (:class:`Cues`);
3. ``photo regions``: the region masks of :func:`~anigs.effects.regions.classify_photo`;
   with ``segmenter.backend`` set, a learned segmenter with local weights gates (or replaces) those
   masks (:mod:`anigs.effects.segmenter`);
4. ``lift``: every Gaussian votes, over the photos where it is visible (depth test), for the region
   under its centre; it joins the region voted by >= ``vote_threshold`` of them, when at least
   ``footprint_share`` of its blending weight over the photos falls on that region's pixels (its
   whole footprint: a blurred splat reaching from a bush over a gate stays still), unless ``photo_vetoes``
   of the photos that show it put less than ``photo_min_share`` of it there (the photos that see it off
   the plant have a say: a splat on a bush in most photos that paints a facade in two stays still). Gaussians no
   photo sees take the majority of their ``propagate_k`` nearest decided neighbours
   (:func:`anigs.geometry.propagate.propagate_labels`); foliage, grass and flowers stop at the ground;
   a prompt that names plants (foliage) but no flowers has the flowers looked for all the same, as the
   plants' blossoms: those the geometry rules keep and the plants hold sway with them
   (``rules.blossoms.with_plants``);
5. ``rules``: the table of geometry rules of :mod:`anigs.effects.rules` on each region's 3D candidates
   (:class:`Ruled`);
6. ``decide`` per region: detected when it covers >= ``min_pixel_fraction`` of the photos' pixels,
   >= ``min_gaussian_fraction`` (and ``min_gaussians``) of the Gaussians and appears in
   >= ``min_photo_fraction`` of the photos (at least 2);
7. what stays still though a photo shows it: per region, the share of its mask pixels with less than
   half of the render from the region's Gaussians (``unlifted`` in the record, :func:`unlifted_share`).
   For foliage, whose mask is the plants' own silhouette, a large share (>= 10%) means the model lacks
   those plants (a crown seen in one photo, placed among what the other photos see as sky): the reason
   says so and the overview hatches them grey.

The user's corrections (``drop``, ``force``, ``boxes``, ``selections``) are the last step
(:mod:`anigs.effects.corrections`, run by :func:`anigs.effects.choice.decide_effects`).

Confidence: detected, ``0.5 + 0.5 * mean(strength_px, strength_g, photo share, agreement)`` with
``strength = min(1, fraction / (3 * minimum))`` and ``agreement`` the mean vote share of the
region's Gaussians; not detected, ``1 - 0.5 * min(1, max(pixel, Gaussian fraction / minimum))``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.effects.analysed import prepare_photos
from anigs.effects.config import EFFECTS, REGION_EFFECTS, REGIONS, EffectsConfig
from anigs.effects.geometry import SHOWN, Ground, render_features
from anigs.effects.lift import lift
from anigs.effects.reasons import UNLIFTED_NOTE, reason, unlifted_note
from anigs.effects.regions import PhotoRegions, classify_photo
from anigs.effects.rules import AFTER, Candidate, check_candidates
from anigs.effects.scene_cues import Cues, scene_cues
from anigs.effects.segmenter import apply_segmenter, region_note
from anigs.gaussians import Gaussians
from anigs.geometry.quaternion import quat_to_rotmat

log = logging.getLogger("anigs.effects")
SH_C0 = 0.28209479  # the degree-0 spherical harmonic: a Gaussian's own colour is 0.5 + SH_C0 x its DC coefficients
SH_OFFSET = 0.5  # ... the 0.5 there: the colour of zero DC coefficients (mid grey, 0..1)
ID_TOL = 0.5  # a rendered region id (1 + region, 0 none) is an id within this: half the step between two (id units)
MIN_PHOTOS = 2  # a region is found in at least this many photos (when there are several; count)
STRONG = 3  # a region's pixel or Gaussian strength is full at this x the least fraction that counts (a factor)
MIN_CONFIDENCE = 0.5  # the least confidence of a decision, found or not (0..1)


@dataclass
class EffectResult:
    """One effect's decision and region (``masks`` per analysed photo, ``indices`` of Gaussians)."""

    name: str
    region: str
    detected: bool
    pixel_fraction: float
    gaussian_fraction: float
    confidence: float
    reason: str
    masks: list[np.ndarray]
    indices: np.ndarray
    photo_fraction: float = 0.0
    agreement: float = 0.0
    unlifted: float = 0.0  # share of the masks' pixels with none of the region's Gaussians in front (they stay still)
    #: per photo: bool [H,W], those pixels (foliage only: the grass, flower and water masks reach past their
    #: plants by design, a lawn's soil, a blossom's rim; empty: none)
    unlifted_masks: list = field(default_factory=list)

    def to_json(self) -> dict:
        return {"detected": bool(self.detected), "pixel_fraction": round(float(self.pixel_fraction), 5),
                "gaussian_fraction": round(float(self.gaussian_fraction), 5),
                "confidence": round(float(self.confidence), 3), "reason": self.reason, "region": self.region,
                "num_gaussians": int(len(self.indices)), "photo_fraction": round(float(self.photo_fraction), 4),
                "agreement": round(float(self.agreement), 4), "unlifted": round(float(self.unlifted), 4)}


@dataclass
class EffectsResult:
    """All effects of a scene, the analysed photos and the per-Gaussian region ids (-1 = none), with what
    the later steps add: the user's corrections (``user_regions``, ``notes``) and how the prompt was read
    (``prompt_lines``, for the overview)."""

    effects: dict[str, EffectResult]
    photos: list[np.ndarray]
    cameras: list[Camera]
    region_of: np.ndarray
    ground: Ground
    cfg: EffectsConfig
    candidates: list[Candidate] = field(default_factory=list)  # numbered 3D candidates, kept or not
    #: per photo: int8 [H,W], 1 + region of a rejected candidate's pixel, 0 none
    rejected_masks: list[np.ndarray] = field(default_factory=list)
    fragments: dict[str, int] = field(default_factory=dict)  # region -> Gaussians of small parts the rules set aside
    segmenter: dict | None = None  # the learned segmenter's record (anigs.effects.segmenter); None: weight-free
    user_regions: list[str] = field(default_factory=list)  # regions the user's corrections make move
    notes: list[str] = field(default_factory=list)  # the corrections' heading and notes (empty: none)
    prompt_lines: list[str] = field(default_factory=list)  # how the prompt was read (anigs.effects.choice)

    @property
    def detected(self) -> list[str]:
        """Names of the detected effects, in ``EFFECTS`` order."""
        return [e for e in EFFECTS if self.effects[e].detected]

    def dynamic(self, effects: Sequence[str] | None = None) -> np.ndarray:
        """bool [N]: Gaussians of the detected effects (of ``effects`` only, when given)."""
        out = np.zeros(len(self.region_of), bool)
        for e in self.detected:
            if effects is None or e in effects:
                out[self.effects[e].indices] = True
        return out

    def to_json(self) -> dict:
        """The ``effects.json`` object: effect name -> decision under ``effects``, plus context."""
        return {"effects": {e: r.to_json() for e, r in self.effects.items()}, "detected": self.detected,
                "num_gaussians": int(len(self.region_of)), "photos": [c.name for c in self.cameras],
                "ground": self.ground.to_dict(), "config": self.cfg.to_dict(),
                "candidates": [c.to_json() for c in self.candidates],
                "rejected": [c.to_json() for c in self.candidates if not c.kept or c.moved_to],
                "fragments": {k: int(v) for k, v in self.fragments.items()},
                **({"segmenter": self.segmenter} if self.segmenter is not None else {})}


@dataclass
class Ruled:
    """Step ``rules``: the new region per Gaussian, the numbered candidates, the small parts set aside per
    region and, per photo, the rejected candidates' pixels (int8 [H,W], 1 + region, 0 none)."""

    region_of: np.ndarray
    candidates: list[Candidate]
    fragments: dict[str, int]
    rejected_masks: list[np.ndarray]


def photo_regions(cues: Cues, cfg: EffectsConfig, looked_for: Sequence[str]) -> tuple[list[PhotoRegions], dict | None]:
    """Step ``photo regions``: each photo's region masks (and the learned segmenter's, when one is set), only
    the regions ``looked_for`` kept; (the masks, the segmenter's record or None)."""
    regions = [classify_photo(p, cues.ground, cfg.regions, cfg.cues, cfg.photos.min_alpha) for p in cues.maps]
    seg_record = None
    if cfg.segmenter.backend != "none":  # learned segmentation gates or replaces the colour cues' regions
        seg_record = apply_segmenter(cues.maps, regions, cfg.segmenter, cfg.photos.min_alpha)
    for reg in regions:  # kinds the prompt does not name are not localised
        for name in REGIONS:
            if name not in looked_for:
                reg.masks[name] = np.zeros_like(reg.masks[name])
    return regions, seg_record


def apply_rules(g: Gaussians, cues: Cues, region_of: np.ndarray, regions: Sequence[PhotoRegions], cfg: EffectsConfig,
                blossoms_of: str | None = None) -> Ruled:
    """Step ``rules``: the geometry rules (:mod:`anigs.effects.rules`) on the lifted regions; the photos' masks
    lose the pixels of rejected candidates and small parts (and sunlit leaves move from flowers to foliage)."""
    means, ground, cams = cues.means, cues.ground, [p.camera for p in cues.maps]
    colours = (SH_OFFSET + SH_C0 * g.sh[:, 0, :]).clamp(0, 1).double().numpy()
    height = cam_h = None
    ref = ground.reference  # the ground, else the lowest dense layer: every rule runs on every capture
    if ref is not None:
        height = means @ ref.normal - ref.offset
        cam_h = ref.camera_height if ref.camera_height > 0 else 1.0
    cam_top = max(float(np.asarray(c.center) @ cues.up) for c in cams)
    new, cands, fragments = check_candidates(means, colours, region_of, height, cam_h or 1.0, cues.radius, cfg,
                                             cues.flat, above_cameras=means @ cues.up > cam_top, blossoms_of=blossoms_of,
                                             flattest=flattest_axes(g))
    for name, count in fragments.items():
        log.info("effects: %d %s Gaussians in parts under %d Gaussians or on no plant (islands) set aside by the rules",
                 count, name, cfg.rules.min_candidate)
    for rule in AFTER:  # the rules on the verdicts (the smeared sheet gives crowns on a "plane" back)
        getattr(cfg.rules, rule.NAME).review(g, cands, new, cues.maps, cfg.photos.min_alpha)
    changed = [c for c in cands if not c.kept or c.moved_to]
    rejected = [np.zeros(p.depth.shape, np.int8) for p in cues.maps]
    for c in changed:
        log.info("effects: candidate %d (%s, %d Gaussians) %s: %s", c.number, c.region, len(c.indices),
                 f"moved to {c.moved_to}" if c.moved_to else "rejected", c.reason)
    dropped = (new == -1) & (region_of >= 0)  # rejected candidates and small parts
    if blossoms_of:  # flowers the prompt did not ask for are not shown as set aside
        dropped &= region_of != REGIONS.index("flowers")
    if not dropped.any() and not changed:
        return Ruled(new, cands, fragments, rejected)
    flags = np.zeros((len(means), 3), np.float32)
    flags[dropped, 0] = 1.0
    flags[dropped, 1] = region_of[dropped] + 1
    for c in changed:
        flags[c.indices, 0] = 1.0
        flags[c.indices, 1] = REGIONS.index(c.region) + 1
        if c.moved_to:
            flags[c.indices, 2] = REGIONS.index(c.moved_to) + 1
    for i, (p, reg) in enumerate(zip(cues.maps, regions)):
        f = render_features(g, flags, p.camera)[0]
        hit = f[..., 0] >= SHOWN
        rejected[i] = np.where(hit & (f[..., 2] < ID_TOL), np.round(f[..., 1]), 0).astype(np.int8)
        for k, name in enumerate(REGIONS):
            was = hit & (np.abs(f[..., 1] - (k + 1)) < ID_TOL)
            reg.masks[name] = reg.masks[name] & ~was
        for k, name in enumerate(REGIONS):
            to = hit & (np.abs(f[..., 2] - (k + 1)) < ID_TOL)
            if to.any():
                reg.masks[name] = reg.masks[name] | to
    return Ruled(new, cands, fragments, rejected)


def flattest_axes(g: Gaussians) -> np.ndarray:
    """[N,3] each Gaussian's unit flattest axis (the rotation's column of its smallest scale): its splat's normal."""
    rot = quat_to_rotmat(g.quats).double().numpy()
    return rot[np.arange(g.num), :, g.scales.argmin(1).numpy()]


def unlifted_share(g: Gaussians, region_of: np.ndarray, cams: Sequence[Camera], masks: dict[str, list[np.ndarray]],
                   min_share: float = SHOWN, out_masks: dict[str, list[np.ndarray]] | None = None) -> dict[str, float]:
    """Per region with mask pixels: the share of its photos' mask pixels (``masks[region]``, one bool [H,W]
    per camera of ``cams``) where the region's Gaussians (``region_of`` [N]) carry less than
    ``min_share`` of the render: the photo shows the region there, the 3D model has none of it (a crown
    seen in one photo, or put where the other photos see sky), so those pixels stay still. ``out_masks``
    (when given) receives, per region, those pixels: bool [H,W] per camera."""
    todo = [r for r in REGIONS if sum(int(m.sum()) for m in masks[r])]
    out = {r: 0.0 for r in REGIONS}
    for part in (todo[:3], todo[3:]):
        if not part:
            continue
        onehot = np.stack([region_of == REGIONS.index(r) for r in part], 1).astype(np.float32)
        miss, tot = np.zeros(len(part)), np.zeros(len(part))
        for i, cam in enumerate(cams):
            share = render_features(g, onehot, cam)[0]
            for j, r in enumerate(part):
                m = masks[r][i]
                missing = m & (share[..., j] < min_share)
                miss[j] += int(missing.sum())
                tot[j] += int(m.sum())
                if out_masks is not None:
                    out_masks.setdefault(r, [np.zeros_like(x) for x in masks[r]])[i] = missing
        out.update({r: float(miss[j] / max(tot[j], 1)) for j, r in enumerate(part)})
    return out


def decide(g: Gaussians, cues: Cues, regions: Sequence[PhotoRegions], ruled: Ruled, share: np.ndarray, cfg: EffectsConfig,
           kinds: Sequence[str], blossoms_of: str | None, seg_record: dict | None) -> dict[str, EffectResult]:
    """Step ``decide``: per region, is it there (``effects.decide``), with its masks, Gaussians, confidence
    and the reason in words; one :class:`EffectResult` per effect."""
    region_of, dc = ruled.region_of, cfg.decide
    cams = [p.camera for p in cues.maps]
    unlifted_px: dict[str, list[np.ndarray]] = {}
    unlifted = unlifted_share(g, region_of, cams, {r: [reg.masks[r] for reg in regions] for r in REGIONS},
                              out_masks=unlifted_px)
    effects: dict[str, EffectResult] = {}
    n_photos = len(cues.maps)
    min_photos = max(MIN_PHOTOS, int(np.ceil(dc.min_photo_fraction * n_photos))) if n_photos > 1 else 1
    for k, name in enumerate(REGIONS):
        masks = [reg.masks[name] for reg in regions]
        fracs = np.array([m.mean() for m in masks])
        pf = float(fracs.mean())
        idx = np.flatnonzero(region_of == k)
        # the blossoms the rules moved onto this region's plants sway with them, but do not make them be there
        carried = sum(len(c.indices) for c in ruled.candidates if c.rule == "blossoms" and c.moved_to == name)
        gf, own_gf = len(idx) / max(len(cues.means), 1), (len(idx) - carried) / max(len(cues.means), 1)
        with_region = int((fracs >= cfg.regions.min_component_frac).sum())
        photo_frac = with_region / n_photos
        agreement = float(share[idx].mean()) if len(idx) else 0.0
        ok = (pf >= dc.min_pixel_fraction and own_gf >= dc.min_gaussian_fraction
              and len(idx) - carried >= dc.min_gaussians and with_region >= min_photos)
        if ok:
            score = np.mean([min(1.0, pf / (STRONG * dc.min_pixel_fraction)),
                             min(1.0, gf / (STRONG * dc.min_gaussian_fraction)), photo_frac, agreement])
            conf = MIN_CONFIDENCE + (1.0 - MIN_CONFIDENCE) * float(score)
        else:
            weak = min(1.0, max(pf / dc.min_pixel_fraction, gf / dc.min_gaussian_fraction))
            conf = 1.0 - (1.0 - MIN_CONFIDENCE) * weak
        rejected = sum(r.rejected_wall_green for r in regions) / max(sum(m.size for m in masks), 1)
        text = reason(name, ok, pf, gf if ok or not carried else own_gf, with_region, n_photos, dc, cues.ground, rejected)
        if carried and not ok:
            text += (f" Not counted: the {carried} Gaussians of blossoms moved onto it (blossoms sway with a plant that "
                     "is there, but do not make it be there).")
        if ok and name == "foliage" and unlifted[name] >= UNLIFTED_NOTE:  # the others' masks grow past them
            text += unlifted_note(name, unlifted[name])
        text += region_note(seg_record, name)
        if name not in kinds:
            text = f"No {name} ({' and '.join(REGION_EFFECTS[name])} skipped): not looked for, the prompt does not name it."
            if name == "flowers" and blossoms_of:
                joined = sum(len(c.indices) for c in ruled.candidates if c.rule == "blossoms" and c.moved_to)
                there = any(e.detected for e in effects.values() if e.region == blossoms_of)
                text = ("No flowers (flower_bob skipped): the prompt names none; " +
                        (f"blossoms on the {blossoms_of} it names sway with it ({joined} Gaussians)." if joined and there
                         else f"blossoms were found on the {blossoms_of} it names ({joined} Gaussians), which is not "
                              "there, so they stay still." if joined else
                         f"no blossoms were found on the {blossoms_of} it names."))
        for eff in REGION_EFFECTS[name]:
            effects[eff] = EffectResult(eff, name, ok, pf, gf, conf, text, masks, idx, photo_frac, agreement,
                                        unlifted[name], unlifted_px.get(name, []) if name == "foliage" else [])
    return effects


def looked_for(kinds: Sequence[str] | None, cfg: EffectsConfig) -> tuple[list[str], str | None, list[str]]:
    """(the kinds to localise, the region whose plants' blossoms the flowers are or None, the regions looked
    for): a prompt that names plants (foliage) but no flowers has the flowers looked for as their blossoms."""
    kinds = list(REGIONS) if kinds is None else list(kinds)
    unknown = [k for k in kinds if k not in REGIONS]
    if unknown:
        raise ValueError(f"detect_effects: unknown kind(s) {unknown}; known: {list(REGIONS)}")
    blossoms_of = "foliage" if cfg.rules.blossoms.with_plants and "foliage" in kinds and "flowers" not in kinds else None
    return kinds, blossoms_of, kinds + ["flowers"] if blossoms_of else kinds


def detect_effects(images: Sequence[np.ndarray], cameras: Sequence[Camera], gaussians: Gaussians,
                   cfg: EffectsConfig | None = None, kinds: Sequence[str] | None = None) -> EffectsResult:
    """Detect foliage, grass, flowers and water in a scene (see module docstring).

    Args:
        images: capture photos, RGB [H,W,3] (float in [0,1] or uint8), one per camera.
        cameras: their cameras (any resolution of the same aspect ratio).
        gaussians: the fitted static model.
        cfg: :class:`EffectsConfig` (defaults documented there).
        kinds: the regions to localise (those the prompt names); None = all of ``REGIONS``. The
            others get empty masks and no Gaussians, with the reason.
    Returns an :class:`EffectsResult` with one :class:`EffectResult` per effect of ``EFFECTS``.
    """
    cfg = cfg or EffectsConfig()
    kinds, blossoms_of, wanted = looked_for(kinds, cfg)
    photos, cams = prepare_photos(images, cameras, cfg.photos)
    g = gaussians.detach()
    cues = scene_cues(g, photos, cams, cfg.cues, cfg.photos.min_alpha)
    regions, seg_record = photo_regions(cues, cfg, wanted)
    region_of, share = lift(g, cues, regions, cfg.lift)
    ruled = apply_rules(g, cues, region_of, regions, cfg, blossoms_of)
    if blossoms_of:  # the blossoms rule moved the held ones to foliage and stilled the rest: no flowers region
        for reg in regions:
            reg.masks["flowers"] = np.zeros_like(reg.masks["flowers"])
    effects = decide(g, cues, regions, ruled, share, cfg, kinds, blossoms_of, seg_record)
    res = EffectsResult(effects, photos, cams, ruled.region_of, cues.ground, cfg, ruled.candidates,
                        ruled.rejected_masks, ruled.fragments, seg_record)
    log.info("effects: detected %s", res.detected or "nothing")
    return res
