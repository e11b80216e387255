"""The contact sheet of final clips (anigs.metrics.contact) on a tiny fake clip with known motion."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.images import write_mask_png
from anigs.metrics.contact import (ContactRow, contact_sheet, heat_colours, load_rows, max_change,
                                   save_contact_sheet)
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.video import save_clip

T, H, W = 5, 24, 32


def _clip(leak: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A grey clip whose left-top block flickers (the mask), plus a leak of ``leak`` at pixel (20, 28)."""
    clip = np.full((T, H, W, 3), 0.5, np.float32)
    mask = np.zeros((H, W), bool)
    mask[2:10, 2:12] = True
    for t in range(T):
        clip[t, 2:10, 2:12] += 0.2 * np.sin(t)
        clip[t, 20, 28] += leak * (t > 0)
    return clip, mask


def test_heat_map_is_black_where_still_and_coloured_where_anything_changes():
    clip, _ = _clip(leak=2 / 255)
    change = max_change(clip)
    assert change[0, 0] == 0 and change[20, 28] == pytest.approx(2 / 255, abs=1e-6)
    heat = heat_colours(change)
    assert (heat[0, 0] == 0).all()                 # still: black
    assert heat[20, 28].max() > 0.1                # a leak of 2/255 shows
    assert heat[5, 5].max() > 0.1                  # the motion shows
    with pytest.raises(ValueError, match="clip"):
        max_change(clip[0])


def test_contact_sheet_rows_columns_and_numbers():
    clip, mask = _clip(leak=0.1)
    effects = {"flower_bob": mask & (np.arange(W) < 6)[None], "foliage_sway": mask & (np.arange(W) >= 6)[None]}
    rows = [ContactRow("v00", clip, mask, effects), ContactRow("v01", clip, None)]
    img, stats = contact_sheet(rows, panel_width=64)
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3
    assert img.shape[1] == 5 * 64 + 4 * 4            # first frame, dynamic, 2 effects, heat map
    s0 = stats[0]
    assert s0["mask_fraction"] == pytest.approx(mask.mean())
    assert set(s0["effects"]) == {"flower_bob", "foliage_sway"}
    # the one leaking pixel is the only changed pixel outside the dilated mask
    outside = (~_dilated(mask)).sum()
    assert s0["outside_still"] == pytest.approx(1 - 1 / outside)
    assert s0["outside_max_change"] == pytest.approx(0.1, abs=1e-6) and s0["mask_moving"] == 1.0
    assert "mask_fraction" not in stats[1]           # no mask: only the clip's own numbers
    with pytest.raises(ValueError, match="does not match"):
        contact_sheet([ContactRow("v00", clip, mask[:-1])])


def _dilated(mask):
    from anigs.pixels import dilate

    return dilate(mask, 5)


def test_load_rows_reads_the_workflow_folders_and_writes_a_png(tmp_path):
    import cv2

    clip, mask = _clip()
    clips, masks = tmp_path / "clips", tmp_path / "masks"
    for v in ("v00", "v10", "v02"):
        save_clip(clips / f"{v}.npz", clip)
    write_mask_png(masks / "v00.png", mask)
    write_mask_png(masks / "v00_flower_bob.png", mask)
    write_mask_png(masks / "v00_overlay.png", mask)  # an overlay is not a mask
    rows = load_rows(clips, MasksOutputs(masks))
    assert [r.name for r in rows] == ["v00", "v02", "v10"]
    assert rows[0].dynamic is not None and (rows[0].dynamic == mask).all()
    assert list(rows[0].effects) == ["flower_bob"] and rows[1].dynamic is None
    stats = save_contact_sheet(tmp_path / "sheet.png", rows, panel_width=48)
    img = cv2.imread(str(tmp_path / "sheet.png"))
    assert img is not None and img.shape[1] == 4 * 48 + 3 * 4 and len(stats) == 3
    with pytest.raises(FileNotFoundError, match="no clips"):
        load_rows(tmp_path / "empty", MasksOutputs(masks))
