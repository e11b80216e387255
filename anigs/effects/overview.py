"""Overview PNG of the detected effects: each region tinted on a few photos, with captions.

Layout: one row per chosen photo (those with the most detected region first, spread over the
capture), one column per region (foliage, grass, flowers, water); a title above each column
names its effects and the decision, and the reasons are printed below the grid. Every numbered
candidate (:mod:`anigs.effects.rules`) is labelled with its number at its centre in its region's
column (white: kept, red: rejected by a geometry rule, whose pixels are hatched red); the
rejections and their reasons are listed below, so a scene file can drop or force a candidate by
number (``effects: {drop: [N], force: [N]}``). Pixels a photo shows as a region with none of the
region's Gaussians in front of them (they stay still; ``unlifted`` in the record) are hatched grey.
"""
from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Sequence

import cv2
import numpy as np

from anigs.effects.config import REGION_EFFECTS, REGIONS
from anigs.effects.detect import EffectsResult
from anigs.effects.segmenter import note as segmenter_note
from anigs.images import write_rgb_png
from anigs.pixels import overlay
from anigs.render.visibility import project_to_pixels

COLOURS = {"foliage": (0.1, 0.95, 0.2), "grass": (1.0, 0.9, 0.1), "flowers": (1.0, 0.2, 0.85), "water": (0.1, 0.8, 1.0)}
FONT = cv2.FONT_HERSHEY_SIMPLEX


def _text_block(lines: list[str], width: int, scale: float = 0.42, colour=(0.0, 0.0, 0.0)) -> np.ndarray:
    """White RGB float block [h, width, 3] with ``lines`` wrapped to fit."""
    chars = max(int(width / (19 * scale)), 20)
    wrapped = [w for line in lines for w in (textwrap.wrap(line, chars) or [""])]
    lh = int(30 * scale) + 4
    block = np.full((lh * len(wrapped) + 8, width, 3), 255, np.uint8)
    ink = tuple(int(255 * c) for c in colour)
    for i, line in enumerate(wrapped):
        cv2.putText(block, line, (6, lh * (i + 1)), FONT, scale, ink, 1, cv2.LINE_AA)
    return block.astype(np.float32) / 255.0


def _pick_photos(res: EffectsResult, count: int) -> list[int]:
    """Photos with the most detected-region pixels, spread over the capture."""
    n = len(res.photos)
    detected_regions = {res.effects[e].region for e in res.detected}
    score = np.zeros(n)
    for r in detected_regions:
        eff = res.effects[REGION_EFFECTS[r][0]]
        score += np.array([m.mean() for m in eff.masks])
    order = []
    for chunk in np.array_split(np.arange(n), min(count, n)):
        order.append(int(chunk[np.argmax(score[chunk])]))
    return order


def _numbers(panel: np.ndarray, res: EffectsResult, photo: int, region: str, scale: float) -> None:
    """Draw the numbers of ``region``'s candidates whose centre photo ``photo`` sees (in place)."""
    cands = [c for c in res.candidates if c.region == region]
    if not cands:
        return
    cam = res.cameras[photo]
    centres = np.array([c.centre for c in cands])
    inside, px, py, _ = project_to_pixels(centres, cam)
    for c, ok, x, y in zip(cands, inside, px, py):
        if not ok:
            continue
        org = (int(x * scale) - 6, int(y * scale) + 4)
        ink = (255, 255, 255) if c.kept and not c.moved_to else (255, 40, 40)
        cv2.putText(panel, str(c.number), org, FONT, 0.4, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(panel, str(c.number), org, FONT, 0.4, ink, 1, cv2.LINE_AA)


def save_overview(path: str | Path, res: EffectsResult, photos: int = 3, panel_width: int = 256,
                  warnings: Sequence[str] = ()) -> None:
    """Write the overview PNG of ``res`` to ``path`` (``photos`` rows, one column per region);
    ``warnings`` (e.g. a static fit too blurry to animate) in red at the top."""
    rows = []
    if warnings:
        width = len(REGIONS) * (panel_width + 4)
        rows.append(_text_block([ln for w in warnings for ln in textwrap.wrap("WARNING: " + w, width // 8)], width,
                                colour=(0.75, 0.05, 0.05)))
    header = []
    for r in REGIONS:
        e = res.effects[REGION_EFFECTS[r][0]]
        state = f"found ({e.confidence:.2f})" if e.detected else f"not found ({e.confidence:.2f})"
        header.append(_text_block([f"{r}: {'+'.join(REGION_EFFECTS[r])}", state], panel_width,
                                  colour=tuple(0.6 * c for c in COLOURS[r]) if e.detected else (0.45, 0.45, 0.45)))
    hh = max(b.shape[0] for b in header)
    rows.append(np.concatenate([np.pad(b, ((0, hh - b.shape[0]), (0, 0), (0, 0)), constant_values=1.0)
                                for b in header], 1))
    for i in _pick_photos(res, photos):
        img = res.photos[i]
        h, w = img.shape[:2]
        ph = int(round(h * panel_width / w))
        panels = []
        for r in REGIONS:
            e = res.effects[REGION_EFFECTS[r][0]]
            m = e.masks[i]
            # pixels the photo shows as the region but no region Gaussian lies in front of stay still: hatched grey
            still = e.unlifted_masks[i] if e.unlifted_masks else np.zeros_like(m)
            tinted = overlay(img, m & ~still, COLOURS[r], 0.55 if e.detected else 0.3)
            grey = still & (((np.arange(h)[:, None] - np.arange(w)[None]) // 2) % 3 == 0)
            tinted = np.where(grey[..., None], np.array([0.55, 0.55, 0.55], np.float32), tinted)
            if not e.detected:
                tinted = 0.55 * tinted + 0.45 * img.mean(-1, keepdims=True)
            if res.rejected_masks:
                rej = res.rejected_masks[i] == REGIONS.index(r) + 1
                hatch = rej & (((np.arange(h)[:, None] + np.arange(w)[None]) // 2) % 3 == 0)
                tinted = np.where(hatch[..., None], np.array([0.95, 0.1, 0.1], np.float32), tinted)
            panel = (np.clip(cv2.resize(tinted, (panel_width, ph), interpolation=cv2.INTER_AREA), 0, 1) * 255
                     ).astype(np.uint8)
            _numbers(panel, res, i, r, panel_width / w)
            moving = f" ({100 * (m & ~still).mean():.1f}% in 3D)" if still.any() else ""
            cv2.putText(panel, f"{res.cameras[i].name} {100 * m.mean():.1f}%{moving}", (4, ph - 6), FONT, 0.38,
                        (255, 255, 255), 1, cv2.LINE_AA)
            panel = panel.astype(np.float32) / 255.0
            panels.append(np.pad(panel, ((2, 2), (2, 2), (0, 0)), constant_values=1.0))
        rows.append(np.concatenate(panels, 1))
    width = rows[-1].shape[1]
    found = res.detected
    lines = ["Effects found: " + (", ".join(found) if found else "none: the scene stays still")]
    lines += res.prompt_lines  # how the prompt was read, and its words not understood
    if res.segmenter:  # the learned segmenter's part (none: weight-free, nothing to say)
        lines.append(segmenter_note(res.segmenter))
    lines += [res.effects[REGION_EFFECTS[r][0]].reason for r in REGIONS]
    if res.ground.note:
        lines.append(res.ground.note)
    changed = [c for c in res.candidates if not c.kept or c.moved_to or c.reason]  # kept with a reason: released
    if res.candidates:
        lines.append(f"{len(res.candidates)} numbered candidates; {len(changed)} changed by geometry "
                     "(drop or force one in the scene file: effects: {drop: [N], force: [N]}):")
    for c in changed[:12]:
        lines.append(f"  #{c.number} {c.region} ({len(c.indices)} Gaussians) "
                     f"{'-> ' + c.moved_to if c.moved_to else 'kept' if c.kept else 'rejected'}: {c.reason}")
    if len(changed) > 12:
        lines.append(f"  ... and {len(changed) - 12} more (the effects record: rejected)")
    for note in res.notes:
        lines.append(note)
    rows.append(_text_block(lines, width))
    rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=1.0) for r in rows]
    write_rgb_png(path, np.concatenate(rows, 0))
