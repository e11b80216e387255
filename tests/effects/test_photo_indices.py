"""The effects stage reads only the photos the detection analyses (anigs.effects.analysed.photo_indices):
picking again from the picked photos keeps every one of them, so the detection sees the same photos."""
from __future__ import annotations

import numpy as np

from anigs.effects.analysed import photo_indices


def test_picked_photos_are_kept_when_picked_again():
    for n in range(1, 400, 7):
        for k in (1, 2, 5, 24, 60):
            pick = photo_indices(n, k)
            assert len(pick) == min(n, k) and len(set(pick.tolist())) == len(pick)
            assert pick[0] == 0 and pick[-1] == (n - 1 if k > 1 else 0)
            np.testing.assert_array_equal(photo_indices(len(pick), k), np.arange(len(pick)))


def test_a_large_capture_reads_only_max_photos():
    assert len(photo_indices(384, 24)) == 24
    np.testing.assert_array_equal(photo_indices(48, 24)[:4], [0, 2, 4, 6])
