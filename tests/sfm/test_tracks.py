"""SfM tracks (anigs.sfm.tracks): the file's round trip, its bytes, its atomic write and bad input.

The tracks of a real COLMAP model are checked against its cameras in tests/sfm/test_sfm.py
(test_ring_outputs_follow_the_contract)."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.io import write_npz
from anigs.sfm.tracks import check_tracks, load_tracks, save_tracks


def _tracks() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {"b.png": np.c_[rng.uniform(0, 640, (5, 2)), rng.uniform(1, 9, 5)].astype(np.float32),
            "a.png": np.c_[rng.uniform(0, 640, (3, 2)), rng.uniform(1, 9, 3)].astype(np.float32),
            "empty.png": np.zeros((0, 3), np.float32)}


def test_round_trip_and_the_same_bytes(tmp_path):
    t = _tracks()
    save_tracks(tmp_path / "t1.npz", t)
    save_tracks(tmp_path / "t2.npz", dict(reversed(list(t.items()))))  # order of the dict does not matter
    assert (tmp_path / "t1.npz").read_bytes() == (tmp_path / "t2.npz").read_bytes()
    back = load_tracks(tmp_path / "t1.npz")
    assert list(back) == ["a.png", "b.png", "empty.png"]
    for k in t:
        assert back[k].dtype == np.float32 and np.array_equal(back[k], t[k]), k


def test_written_atomically(tmp_path, monkeypatch):
    path = tmp_path / "tracks.npz"
    save_tracks(path, _tracks())
    before = path.read_bytes()

    def broken(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(np.lib.format, "write_array", broken)
    with pytest.raises(OSError, match="disk full"):
        save_tracks(path, {"c.png": np.ones((2, 3), np.float32)})
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tracks.npz"]


def test_bad_rows_name_the_image(tmp_path):
    t = _tracks()
    t["b.png"][1, 0] = np.nan
    with pytest.raises(ValueError, match="'b.png' has 1 non-finite"):
        save_tracks(tmp_path / "t.npz", t)
    with pytest.raises(ValueError, match="'a.png' has 1 rows with depth <= 0"):
        check_tracks({"a.png": np.array([[1.0, 2.0, -1.0]])})
    with pytest.raises(ValueError, match=r"'a.png' has rows of shape \(4,\)"):
        check_tracks({"a.png": np.ones(4)})


def test_bad_files_are_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="sfm stage writes tracks.npz"):
        load_tracks(tmp_path / "none.npz")
    write_npz(tmp_path / "m.npz", names=np.array(["a.png"]), rows=np.ones((1, 3), np.float32))
    with pytest.raises(ValueError, match=r"missing array\(s\) \['offsets'\]"):
        load_tracks(tmp_path / "m.npz")
    write_npz(tmp_path / "o.npz", names=np.array(["a.png"]), offsets=np.array([0, 5]), rows=np.ones((1, 3), np.float32))
    with pytest.raises(ValueError, match="do not index 1 rows of 1 images"):
        load_tracks(tmp_path / "o.npz")
    write_npz(tmp_path / "n.npz", names=np.array(["a.png"]), offsets=np.array([0, 1]),
              rows=np.array([[1.0, np.inf, 2.0]], np.float32))
    with pytest.raises(ValueError, match="n.npz: image 'a.png' has 1 non-finite"):
        load_tracks(tmp_path / "n.npz")
