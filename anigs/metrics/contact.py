"""Contact sheet of the final clips: where things move, against where they may.

One row per view: the first frame, each mask tinted over it (the dynamic mask, then one per
effect), and a heat map of the largest change from frame 0 over the clip,
``max_t |I_t - I_0|`` (any channel), with the outline of the dynamic mask dilated by
``margin_px`` (the region ``static_outside_mask_still`` excludes, :func:`outside_mask_still`).
Black in the heat map is still (a change of at most ``tolerance``); colours run from blue (just
above it) to red (``vmax`` and more) on a log scale, so a leak of 2/255 outside the outline is as
visible as the motion inside it. A caption under each row gives the numbers.

    from anigs.metrics.contact import load_rows, save_contact_sheet
    rows = load_rows("results/S/full/final/clips", masks)  # masks: the masks stage's Outputs (MaskFiles)
    save_contact_sheet("contact.png", rows)
"""
from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from anigs.contract import MaskFiles
from anigs.io import atomic_path
from anigs.metrics.motion import outside_mask_still, resize_mask
from anigs.pixels import dilate
from anigs.video import load_clip

FONT = cv2.FONT_HERSHEY_SIMPLEX
MASK_COLOURS = [(1.0, 0.15, 0.6), (0.1, 0.95, 0.2), (1.0, 0.85, 0.1), (0.1, 0.8, 1.0), (1.0, 0.5, 0.1)]
OUTLINE = (1.0, 1.0, 1.0)


@dataclass
class ContactRow:
    """One view of the sheet: its clip and masks at the clip's size (bool [H,W])."""

    name: str
    clip: np.ndarray                       # [T,H,W,3] in [0,1]
    dynamic: np.ndarray | None = None      # the view's dynamic mask (None: no mask)
    effects: dict[str, np.ndarray] = field(default_factory=dict)  # per-effect masks


def max_change(clip: np.ndarray) -> np.ndarray:
    """float32 [H,W]: ``max_t |I_t - I_0|`` over frames and channels of a clip [T,H,W,3]."""
    clip = np.asarray(clip, np.float32)
    if clip.ndim != 4 or clip.shape[-1] != 3 or clip.shape[0] < 1:
        raise ValueError(f"max_change: expected a clip [T,H,W,3], got {clip.shape}")
    return np.abs(clip - clip[:1]).max(axis=(0, 3))


def heat_colours(change: np.ndarray, tolerance: float = 1 / 255, vmax: float = 0.5) -> np.ndarray:
    """RGB float [H,W,3]: black where ``change <= tolerance`` (still), else a turbo colour of
    ``log(change)`` between ``tolerance`` (blue) and ``vmax`` (red)."""
    if not 0 < tolerance < vmax:
        raise ValueError(f"heat_colours: need 0 < tolerance < vmax, got {tolerance}, {vmax}")
    c = np.asarray(change, np.float32)
    t = (np.log(np.maximum(c, tolerance)) - np.log(tolerance)) / (np.log(vmax) - np.log(tolerance))
    idx = (0.15 + 0.85 * np.clip(t, 0, 1)) * 255  # skip turbo's near-black start: black means still
    bgr = cv2.applyColorMap(idx.astype(np.uint8), cv2.COLORMAP_TURBO)
    rgb = bgr[..., ::-1].astype(np.float32) / 255.0
    rgb[c <= tolerance + 1e-6] = 0.0
    return rgb


def outline(mask: np.ndarray, width: int = 1) -> np.ndarray:
    """bool [H,W]: the inner boundary of ``mask``, ``width`` px thick."""
    m = np.asarray(mask, bool).astype(np.uint8)
    k = np.ones((2 * width + 1, 2 * width + 1), np.uint8)
    return (m - cv2.erode(m, k, borderType=cv2.BORDER_CONSTANT, borderValue=0)) > 0


def tint(image: np.ndarray, mask: np.ndarray, colour, strength: float = 0.5) -> np.ndarray:
    """RGB float [H,W,3]: ``image`` with ``mask`` tinted and outlined in ``colour``."""
    out = np.array(image, np.float32, copy=True)
    m = np.asarray(mask, bool)
    col = np.asarray(colour, np.float32)
    out[m] = (1 - strength) * out[m] + strength * col
    out[outline(m)] = col
    return out


def row_stats(row: ContactRow, margin_px: int = 5, tolerance: float = 1 / 255) -> dict[str, Any]:
    """The numbers of a row's caption: mask fractions, the share of still pixels outside the dilated
    mask (as eval's ``static_outside_mask_still``), the largest change there and the share of the
    mask that moves at all."""
    change = max_change(row.clip)
    st: dict[str, Any] = {"view": row.name, "frames": int(row.clip.shape[0]),
                          "max_change": float(change.max())}
    if row.dynamic is None:
        return st
    dyn = np.asarray(row.dynamic, bool)
    outside = ~dilate(dyn, margin_px)
    moving = change > tolerance + 1e-6
    st.update({"mask_fraction": float(dyn.mean()),
               "effects": {e: float(np.asarray(m, bool).mean()) for e, m in row.effects.items()},
               "outside_still": outside_mask_still(row.clip, dyn, margin_px, tolerance),
               "outside_max_change": float(change[outside].max()) if outside.any() else float("nan"),
               "mask_moving": float(moving[dyn].mean()) if dyn.any() else float("nan")})
    return st


def _text(lines: Sequence[str], width: int, scale: float = 0.42, ink=(0, 0, 0)) -> np.ndarray:
    """White uint8 RGB block [h, width, 3] with ``lines`` (cut to fit the width)."""
    lh = int(30 * scale) + 4
    block = np.full((lh * len(lines) + 6, width, 3), 255, np.uint8)
    max_chars = max(int(width / (19 * scale)), 8)
    for i, line in enumerate(lines):
        cv2.putText(block, line[:max_chars], (4, lh * (i + 1)), FONT, scale, ink, 1, cv2.LINE_AA)
    return block


def _fit(img: np.ndarray, w: int, h: int) -> np.ndarray:
    u8 = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8) if img.dtype != np.uint8 else img
    if u8.shape[:2] != (h, w):
        u8 = cv2.resize(u8, (w, h), interpolation=cv2.INTER_NEAREST if w >= u8.shape[1] else cv2.INTER_AREA)
    return u8


def _colour_bar(width: int, tolerance: float, vmax: float) -> np.ndarray:
    """The heat map's legend: the colour ramp with ticks, and what black means."""
    bar_h, pad = 14, 10
    xs = np.geomspace(tolerance, vmax, max(width - 2 * pad, 2))
    ramp = heat_colours(np.tile(xs * 1.0001, (bar_h, 1)), tolerance, vmax)
    block = np.full((bar_h + 40, width, 3), 255, np.uint8)
    block[4:4 + bar_h, pad:width - pad] = _fit(ramp, width - 2 * pad, bar_h)
    for v in (tolerance, 0.01, 0.03, 0.1, 0.3, vmax):
        if not tolerance <= v <= vmax:
            continue
        x = pad + int(round((np.log(v) - np.log(tolerance)) / (np.log(vmax) - np.log(tolerance)) * (width - 2 * pad - 1)))
        label = "1/255" if abs(v - 1 / 255) < 1e-9 else f"{v:g}"
        cv2.line(block, (x, 4 + bar_h), (x, 8 + bar_h), (0, 0, 0), 1)
        cv2.putText(block, label, (max(x - 12, 0), bar_h + 20), FONT, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(block, "max |I_t - I_0| (log); black: still; white line: dilated mask", (pad, bar_h + 36),
                FONT, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
    return block


def contact_sheet(rows: Sequence[ContactRow], margin_px: int = 5, tolerance: float = 1 / 255,
                  vmax: float = 0.5, panel_width: int = 256) -> tuple[np.ndarray, list[dict[str, Any]]]:
    """Draw the sheet: (uint8 RGB [H,W,3], the per-row numbers of :func:`row_stats`).

    Columns: first frame, dynamic mask, one per effect seen in any row (a grey panel where a row
    lacks it), heat map. ``margin_px`` and ``tolerance`` as eval's ``still_margin_px`` and
    ``still_tolerance``."""
    if not rows:
        raise ValueError("contact_sheet: no rows")
    effects = sorted({e for r in rows for e in r.effects})
    titles = ["first frame", "mask: dynamic", *[f"mask: {e}" for e in effects],
              f"max change (mask +{margin_px} px)"]
    h0, w0 = rows[0].clip.shape[1:3]
    pw = int(panel_width)
    ph = max(int(round(pw * h0 / w0)), 1)
    gap = 4
    sheet_w = len(titles) * pw + (len(titles) - 1) * gap

    def hstack(panels: list[np.ndarray]) -> np.ndarray:
        sep = np.full((panels[0].shape[0], gap, 3), 255, np.uint8)
        out = [panels[0]]
        for p in panels[1:]:
            out += [sep, p]
        return np.concatenate(out, 1)

    parts = [hstack([_text([t], pw, 0.45) for t in titles])]
    stats = []
    for row in rows:
        clip = np.asarray(row.clip, np.float32)
        if clip.ndim != 4 or clip.shape[-1] != 3:
            raise ValueError(f"contact_sheet: view {row.name}: expected a clip [T,H,W,3], got {clip.shape}")
        H, W = clip.shape[1:3]
        for what, m in [("dynamic", row.dynamic), *row.effects.items()]:
            if m is not None and np.asarray(m).shape != (H, W):
                raise ValueError(f"contact_sheet: view {row.name}: {what} mask {np.asarray(m).shape} "
                                 f"does not match the clip's frames {(H, W)}")
        st = row_stats(row, margin_px, tolerance)
        stats.append(st)
        first = clip[0]
        grey = np.full((ph, pw, 3), 200, np.uint8)
        panels = [_fit(first, pw, ph)]
        panels.append(_fit(tint(first, row.dynamic, MASK_COLOURS[0]), pw, ph) if row.dynamic is not None else grey)
        for k, e in enumerate(effects):
            m = row.effects.get(e)
            panels.append(grey if m is None else _fit(tint(first, m, MASK_COLOURS[(k + 1) % len(MASK_COLOURS)]), pw, ph))
        heat = heat_colours(max_change(clip), tolerance, vmax)
        if row.dynamic is not None:
            heat[outline(dilate(np.asarray(row.dynamic, bool), margin_px))] = OUTLINE
        panels.append(_fit(heat, pw, ph))
        parts.append(hstack(panels))
        cap = f"{row.name}: {clip.shape[0]} frames {W}x{H}, max change {st['max_change']:.3f}"
        if row.dynamic is None:
            lines = [cap + "; no mask"]
        else:
            eff = ", ".join(f"{e} {100 * v:.1f}%" for e, v in st["effects"].items())
            lines = [cap + f"; mask {100 * st['mask_fraction']:.1f}%" + (f" ({eff})" if eff else ""),
                     (f"outside the dilated mask: still {st['outside_still']:.3f}, largest change "
                      f"{st['outside_max_change']:.3f}; inside the mask {100 * st['mask_moving']:.0f}% of pixels move")]
        parts.append(_text(lines, sheet_w))
    parts.append(np.concatenate([np.full((54, sheet_w - pw, 3), 255, np.uint8), _colour_bar(pw, tolerance, vmax)], 1))
    return np.concatenate(parts, 0), stats


def _view_key(name: str) -> tuple:
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))


def load_rows(clips_dir: str | Path, masks: MaskFiles | None, threshold: float = 0.5,
              views: Sequence[str] | None = None) -> list[ContactRow]:
    """Rows from the workflow's folders: ``clips_dir/{view}.npz`` (:func:`anigs.video.load_clip`) and
    the masks stage's folder ``masks``: each view's mask and per-effect masks, resized to each
    clip as eval resizes them (``threshold``: eval's ``mask_threshold``)."""
    clips_dir = Path(clips_dir)
    names = list(views) if views is not None else sorted((p.stem for p in clips_dir.glob("*.npz")), key=_view_key)
    if not names:
        raise FileNotFoundError(f"no clips (*.npz) in {clips_dir}")
    rows = []
    for name in names:
        clip, _ = load_clip(clips_dir / f"{name}.npz")
        H, W = clip.shape[1:3]
        dyn, effects = None, {}
        if masks is not None:
            if masks.has_view_mask(name):
                dyn = resize_mask(masks.view_mask(name), H, W, threshold)
            for effect, m in masks.effect_masks(name).items():
                effects[effect] = resize_mask(m, H, W, threshold)
        rows.append(ContactRow(name, clip, dyn, effects))
    return rows


def save_contact_sheet(path: str | Path, rows: Sequence[ContactRow], **kwargs: Any) -> list[dict[str, Any]]:
    """Draw :func:`contact_sheet` into the PNG ``path`` (atomically); returns the per-row numbers."""
    img, stats = contact_sheet(rows, **kwargs)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), img[..., ::-1]):
            raise RuntimeError(f"could not write contact sheet {path}")
    return stats
