"""Which effects a scene contains and where: :func:`detect_effects` and its result.

Pipeline (no downloaded weights):

1. a few capture photos (``max_photos``, evenly spaced, downscaled to ``max_side``);
2. 3D cues of the fitted model: up, ground plane, per-Gaussian surface variation and
   ``|normal . up|`` (:func:`~anigs.effects.geometry.local_shape`), multi-view colour spread;
3. per photo: the model's depth/alpha and the cue maps rendered at its camera, then the region
   masks of :func:`~anigs.effects.regions.classify_photo`;
   with ``segmenter.backend`` set, a learned segmenter with local weights gates (or replaces) those
   masks (:mod:`anigs.effects.segmenter`);
4. lift: every Gaussian votes, over the photos where it is visible (depth test), for the region
   under its centre; it joins the region voted by >= ``vote_threshold`` of them, when at least
   ``footprint_share`` of its blending weight over the photos falls on that region's pixels (its
   whole footprint: a blurred splat reaching from a bush over a gate stays still). Gaussians no
   photo sees take the majority of their ``propagate_k`` nearest decided neighbours
   (:func:`anigs.geometry.propagate.propagate_labels`); foliage, grass and flowers stop at the ground;
   a prompt that names plants (foliage) but no flowers has the flowers looked for all the same, as the
   plants' blossoms: those the geometry rules keep and the plants hold sway with them
   (``blossoms_with_plants``; rule 5 of :mod:`anigs.effects.rules`);
5. decide per region: detected when it covers >= ``min_pixel_fraction`` of the photos' pixels,
   >= ``min_gaussian_fraction`` (and ``min_gaussians``) of the Gaussians and appears in
   >= ``min_photo_fraction`` of the photos (at least 2);
6. what stays still though a photo shows it: per region, the share of its mask pixels with less than
   half of the render from the region's Gaussians (``unlifted`` in the record, :func:`unlifted_share`).
   For foliage, whose mask is the plants' own silhouette, a large share (>= 10%) means the model lacks
   those plants (a crown seen in one photo, placed among what the other photos see as sky): the reason
   says so and the overview hatches them grey.

Confidence: detected, ``0.5 + 0.5 * mean(strength_px, strength_g, photo share, agreement)`` with
``strength = min(1, fraction / (3 * minimum))`` and ``agreement`` the mean vote share of the
region's Gaussians; not detected, ``1 - 0.5 * min(1, max(pixel, Gaussian fraction / minimum))``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Sequence

import cv2
import numpy as np

from anigs.cameras import Camera
from anigs.effects.config import EFFECTS, REGION_EFFECTS, REGIONS, Config
from anigs.effects.geometry import (Ground, colour_spread, local_shape, render_features, scene_ground, seen_ground_cut,
                                   world_up)
from anigs.effects.reasons import UNLIFTED_NOTE, reason, unlifted_note
from anigs.effects.analysed import prepare_photos
from anigs.effects.outline import release_smeared
from anigs.effects.regions import PhotoMaps, PhotoRegions, classify_photo
from anigs.effects.rules import check_candidates
from anigs.gaussians import Gaussians
from anigs.render.visibility import VisibilityConfig, blend_weights, project_to_pixels, visible_depth
from anigs.geometry.propagate import propagate_labels

log = logging.getLogger("anigs.effects")


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
    """All effects of a scene, the analysed photos and the per-Gaussian region ids (-1 = none)."""

    effects: dict[str, EffectResult]
    photos: list[np.ndarray]
    cameras: list[Camera]
    region_of: np.ndarray
    ground: Ground
    cfg: Config
    candidates: list = field(default_factory=list)  # numbered 3D candidates (anigs.effects.rules.Candidate)
    rejected_masks: list = field(default_factory=list)  # per photo: int8 [H,W], 1 + region of a rejected candidate's pixel, 0 none
    fragments: dict = field(default_factory=dict)  # region -> Gaussians of unnumbered small parts the rules set aside
    segmenter: dict | None = None  # the learned segmenter's record (anigs.effects.segmenter); None: weight-free

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


def _median_depth(means: np.ndarray, cams: Sequence[Camera]) -> float:
    zs = []
    for cam in cams:
        inside, _, _, z = project_to_pixels(means, cam)
        if inside.any():
            zs.append(float(np.median(z[inside])))
    if not zs:
        raise ValueError("detect_effects: no Gaussian lies in front of any photo's camera")
    return float(np.median(zs))


def footprint_shares(g: Gaussians, maps: Sequence[PhotoMaps], regions: Sequence[PhotoRegions],
                     reach: int = 0) -> np.ndarray:
    """Per Gaussian and region: the share [N, R] of its blending weight, summed over the photos, that falls
    on the region's mask pixels or within ``reach`` px of them (its whole footprint,
    :func:`~anigs.render.visibility.blend_weights`; the reach forgives a splat's soft edge); 0 for a
    Gaussian no photo renders and for a region no photo shows."""
    total = np.zeros(g.num)
    inside = np.zeros((g.num, len(REGIONS)))
    grow = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    for p, reg in zip(maps, regions):
        shown = [k for k, name in enumerate(REGIONS) if reg.masks[name].any()]
        for j in range(0, max(len(shown), 1), 2):  # two masks per pass; one pass for the total at least
            pair = shown[j:j + 2]
            masks = [reg.masks[REGIONS[k]].astype(np.uint8) for k in pair]
            masks = [cv2.dilate(m, grow) if reach > 0 else m for m in masks]
            t, w = blend_weights(g, p.camera, np.stack(masks, -1) if masks else None)
            if pair:
                inside[:, pair] += w
            total += t if j == 0 else 0.0
    return inside / np.maximum(total, 1e-12)[:, None]


def _lift(g: Gaussians, means: np.ndarray, max_scale: np.ndarray, maps: Sequence[PhotoMaps],
          regions: Sequence[PhotoRegions], ground: Ground, cfg: Config) -> tuple[np.ndarray, np.ndarray]:
    """Region id [N] (-1 none) and vote share [N] of every Gaussian (see module docstring)."""
    n, r = len(means), len(REGIONS)
    votes = np.zeros((n, r + 1))
    seen_n = np.zeros(n)
    vis = VisibilityConfig(mode="depth")
    for p, reg in zip(maps, regions):
        ids = np.zeros(p.depth.shape, np.int64)
        for k, name in enumerate(REGIONS):
            ids[reg.masks[name]] = k + 1
        seen = visible_depth(means, p.camera, p.depth, p.alpha, max_scale, vis)
        _, px, py, _ = project_to_pixels(means, p.camera, vis.near)
        np.add.at(votes, (np.flatnonzero(seen), ids[py[seen], px[seen]]), 1.0)
        seen_n += seen
    share = votes[:, 1:] / np.maximum(seen_n, 1)[:, None]
    best = np.argmax(share, 1)
    top = share[np.arange(n), best]
    region = np.where(top >= cfg.vote_threshold, best, -1)
    decided = seen_n > 0
    foot = None
    if cfg.footprint_share > 0 and (region >= 0).any():
        foot = footprint_shares(g, maps, regions, cfg.footprint_reach_px)
        region[(region >= 0) & (foot[np.arange(n), best] < cfg.footprint_share)] = -1
    out = region.copy()
    for k in range(r):
        out[propagate_labels(means, decided, region == k, cfg.propagate_k) & ~decided] = k
    if foot is not None:  # a Gaussian no photo sees in the depth test but that renders elsewhere: its footprint too
        late = (out >= 0) & ~decided
        out[late & (foot[np.arange(n), np.maximum(out, 0)] < cfg.footprint_share) & (foot.sum(1) > 0)] = -1
    if ground.plane is not None:  # plants stop at the ground (water lies on it)
        hgt = means @ ground.plane.normal - ground.plane.offset
        below = hgt < 0.5 * ground.plane.min_height
        out[below & np.isin(out, [REGIONS.index(x) for x in ("foliage", "grass", "flowers")])] = -1
    return out, np.where(decided, top, 0.0)


def _apply_rules(g: Gaussians, means: np.ndarray, region_of: np.ndarray, ground: Ground, radius: float,
                 maps: Sequence[PhotoMaps], regions: Sequence[PhotoRegions], cfg: Config,
                 flat: np.ndarray, cams: Sequence[Camera] = (), blossoms_of: str | None = None
                 ) -> tuple[np.ndarray, list, dict]:
    """The geometry rules (:mod:`anigs.effects.rules`) on the lifted regions; the photos' masks lose
    the pixels of rejected candidates and small parts (and sunlit leaves move from flowers to foliage)."""
    colours = (0.5 + 0.28209479 * g.sh[:, 0, :]).clamp(0, 1).double().numpy()
    height = cam_h = None
    if ground.plane is not None:
        height = means @ ground.plane.normal - ground.plane.offset
        cam_h = ground.plane.camera_height if ground.plane.camera_height > 0 else 1.0
    up = world_up(cams, cfg.up, means) if cams else np.array([0.0, 0.0, 1.0])
    cam_top = max(float(np.asarray(c.center) @ up) for c in cams) if cams else np.inf
    new, cands, fragments = check_candidates(means, colours, region_of, height, cam_h or 1.0, radius, cfg, flat,
                                             above_cameras=means @ up > cam_top, blossoms_of=blossoms_of)
    for name, count in fragments.items():
        log.info("effects: %d %s Gaussians in parts under %d Gaussians or on no plant (islands) set aside by the rules", count, name,
                 cfg.min_candidate)
    release_smeared(g, cands, new, maps, cfg)  # sheets a sparse fit smeared along the rays are plants
    changed = [c for c in cands if not c.kept or c.moved_to]
    for p in maps:
        p.rejected = np.zeros(p.depth.shape, np.int8)
    for c in changed:
        log.info("effects: candidate %d (%s, %d Gaussians) %s: %s", c.number, c.region, len(c.indices),
                 f"moved to {c.moved_to}" if c.moved_to else "rejected", c.reason)
    dropped = (new == -1) & (region_of >= 0)  # rejected candidates and small parts
    if blossoms_of:  # flowers the prompt did not ask for are not shown as set aside
        dropped &= region_of != REGIONS.index("flowers")
    if not dropped.any() and not changed:
        return new, cands, fragments
    flags = np.zeros((len(means), 3), np.float32)
    flags[dropped, 0] = 1.0
    flags[dropped, 1] = region_of[dropped] + 1
    for c in changed:
        flags[c.indices, 0] = 1.0
        flags[c.indices, 1] = REGIONS.index(c.region) + 1
        if c.moved_to:
            flags[c.indices, 2] = REGIONS.index(c.moved_to) + 1
    for p, reg in zip(maps, regions):
        f = render_features(g, flags, p.camera)[0]
        hit = f[..., 0] >= 0.5
        p.rejected = np.where(hit & (f[..., 2] < 0.5), np.round(f[..., 1]), 0).astype(np.int8)
        for k, name in enumerate(REGIONS):
            was = hit & (np.abs(f[..., 1] - (k + 1)) < 0.5)
            reg.masks[name] = reg.masks[name] & ~was
        for k, name in enumerate(REGIONS):
            to = hit & (np.abs(f[..., 2] - (k + 1)) < 0.5)
            if to.any():
                reg.masks[name] = reg.masks[name] | to
    return new, cands, fragments


def unlifted_share(g: Gaussians, region_of: np.ndarray, cams: Sequence[Camera], masks: dict[str, list[np.ndarray]],
                   min_share: float = 0.5, out_masks: dict[str, list[np.ndarray]] | None = None) -> dict[str, float]:
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


def detect_effects(images: Sequence[np.ndarray], cameras: Sequence[Camera], gaussians: Gaussians,
                   cfg: Config | None = None, kinds: Sequence[str] | None = None) -> EffectsResult:
    """Detect foliage, grass, flowers and water in a scene (see module docstring).

    Args:
        images: capture photos, RGB [H,W,3] (float in [0,1] or uint8), one per camera.
        cameras: their cameras (any resolution of the same aspect ratio).
        gaussians: the fitted static model.
        cfg: :class:`Config` (defaults documented there).
        kinds: the regions to localise (those the prompt names); None = all of ``REGIONS``. The
            others get empty masks and no Gaussians, with the reason.
    Returns an :class:`EffectsResult` with one :class:`EffectResult` per effect of ``EFFECTS``.
    """
    cfg = cfg or Config()
    photos, cams = prepare_photos(images, cameras, cfg)
    g = gaussians.detach()
    means = g.means.double().numpy()
    max_scale = g.scales.max(1).values.double().numpy()
    up = world_up(cams, cfg.up, means)
    ground = scene_ground(means, cams, up, cfg.ground_margin, cfg.ground_min_support, cfg.ground_max_below)
    if ground.note:
        log.info("effects: %s", ground.note)
    radius = cfg.neighbour_radius * _median_depth(means, cams)
    variation, upness = local_shape(means, up, radius, cfg.neighbours)
    shape = np.column_stack([variation, upness])
    renders = [render_features(g, shape, cam) for cam in cams]
    spread = colour_spread(g, photos, cams, [r[2] for r in renders])
    second = [spread]
    if ground.plane is not None:
        second.append(means @ ground.plane.normal - ground.plane.offset)
    second = np.column_stack(second)
    maps = []
    for img, cam, (m, a, d) in zip(photos, cams, renders):
        m2 = render_features(g, second, cam)[0]
        height = m2[..., 1] if ground.plane is not None else None
        maps.append(PhotoMaps(img, cam, d, a, m[..., 0], m[..., 1], m2[..., 0], height, cam.name))
    if ground.plane is not None:
        seen = [np.where((p.alpha >= cfg.min_alpha) & (p.depth > 0), p.height, np.nan) for p in maps]
        ground.cut = seen_ground_cut(ground.plane, seen, cfg.ground_seen_quantile)
        log.info("effects: ground cut %.3g above the plane (seen ground; the centres' layer reaches %.3g)",
                 ground.cut, ground.plane.cut_height())
    regions = [classify_photo(p, ground, cfg) for p in maps]
    seg_record = None
    if cfg.segmenter.backend != "none":  # learned segmentation gates or replaces the colour cues' regions
        from anigs.effects.segmenter import apply_segmenter

        seg_record = apply_segmenter(maps, regions, cfg.segmenter, cfg.min_alpha)
    kinds = list(REGIONS) if kinds is None else list(kinds)
    unknown = [k for k in kinds if k not in REGIONS]
    if unknown:
        raise ValueError(f"detect_effects: unknown kind(s) {unknown}; known: {list(REGIONS)}")
    # a flowering plant's blossoms sway with it: flowers are looked for as the named plants' blossoms
    blossoms_of = "foliage" if cfg.blossoms_with_plants and "foliage" in kinds and "flowers" not in kinds else None
    looked_for = kinds + ["flowers"] if blossoms_of else kinds
    for reg in regions:  # kinds the prompt does not name are not localised
        for name in REGIONS:
            if name not in looked_for:
                reg.masks[name] = np.zeros_like(reg.masks[name])
    region_of, share = _lift(g, means, max_scale, maps, regions, ground, cfg)
    region_of, candidates, fragments = _apply_rules(g, means, region_of, ground, radius, maps, regions, cfg,
                                                    variation < cfg.wall_max_variation, cams, blossoms_of)
    if blossoms_of:  # rule 5 moved the held blossoms to foliage and stilled the rest: no flowers region of its own
        for reg in regions:
            reg.masks["flowers"] = np.zeros_like(reg.masks["flowers"])
    unlifted_px: dict[str, list[np.ndarray]] = {}
    unlifted = unlifted_share(g, region_of, cams, {r: [reg.masks[r] for reg in regions] for r in REGIONS},
                              out_masks=unlifted_px)
    effects: dict[str, EffectResult] = {}
    n_photos = len(maps)
    min_photos = max(2, int(np.ceil(cfg.min_photo_fraction * n_photos))) if n_photos > 1 else 1
    for k, name in enumerate(REGIONS):
        masks = [reg.masks[name] for reg in regions]
        fracs = np.array([m.mean() for m in masks])
        pf = float(fracs.mean())
        idx = np.flatnonzero(region_of == k)
        gf = len(idx) / max(len(means), 1)
        with_region = int((fracs >= cfg.min_component_frac).sum())
        photo_frac = with_region / n_photos
        agreement = float(share[idx].mean()) if len(idx) else 0.0
        ok = (pf >= cfg.min_pixel_fraction and gf >= cfg.min_gaussian_fraction and len(idx) >= cfg.min_gaussians
              and with_region >= min_photos)
        if ok:
            score = np.mean([min(1.0, pf / (3 * cfg.min_pixel_fraction)), min(1.0, gf / (3 * cfg.min_gaussian_fraction)),
                             photo_frac, agreement])
            conf = 0.5 + 0.5 * float(score)
        else:
            conf = 1.0 - 0.5 * min(1.0, max(pf / cfg.min_pixel_fraction, gf / cfg.min_gaussian_fraction))
        rejected = sum(r.rejected_wall_green for r in regions) / max(sum(m.size for m in masks), 1)
        text = reason(name, ok, pf, gf, with_region, n_photos, cfg, ground, rejected)
        if ok and name == "foliage" and unlifted[name] >= UNLIFTED_NOTE:  # the others' masks grow past them
            text += unlifted_note(name, unlifted[name])
        if seg_record is not None:
            from anigs.effects.segmenter import region_note

            text += region_note(seg_record, name)
        if name not in kinds:
            text = f"No {name} ({' and '.join(REGION_EFFECTS[name])} skipped): not looked for, the prompt does not name it."
            if name == "flowers" and blossoms_of:
                joined = sum(len(c.indices) for c in candidates if c.rule == "blossoms" and c.moved_to)
                text = ("No flowers (flower_bob skipped): the prompt names none; " +
                        (f"blossoms on the {blossoms_of} it names sway with it ({joined} Gaussians)." if joined else
                         f"no blossoms were found on the {blossoms_of} it names."))
        for eff in REGION_EFFECTS[name]:
            effects[eff] = EffectResult(eff, name, ok, pf, gf, conf, text, masks, idx, photo_frac, agreement,
                                        unlifted[name], unlifted_px.get(name, []) if name == "foliage" else [])
    res = EffectsResult(effects, photos, cams, region_of, ground, cfg, candidates,
                        [getattr(p, "rejected", np.zeros(p.depth.shape, np.int8)) for p in maps], fragments,
                        seg_record)
    log.info("effects: detected %s", res.detected or "nothing")
    return res
