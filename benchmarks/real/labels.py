"""Hand-made labels of the real-capture benchmark: what must move and what must stay still.

A label file ``benchmarks/real/labels/<capture>.json`` holds, per labelled photo (its file name in
the capture folder), polygons in the pixel coordinates of the original photo as an image viewer
shows it (EXIF orientation applied)::

    {"capture": NAME, "expects_motion": bool, "absent": [effects the photos do not hold, e.g. "flower_bob"],
     "note": "what was marked and why",
     "photos": {"image001.png": {"move": [{"what": "fronds", "points": [[x, y], ...]}, ...],
                                 "still": [{"what": "trunk", "points": [...]}, ...]}}}

Unmarked pixels are what a person could argue about; they count for nothing.

    python benchmarks/real/labels.py --captures ../shared/captures --out /tmp/labels [CAPTURE ...]

draws every capture's polygons over its photos (green: must move, red: must stay still) into
``--out/<capture>.png`` so a person can check that they sit where they were meant.
"""
from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

LABELS = Path(__file__).resolve().parent / "labels"


@dataclass
class Polygon:
    """One marked region: ``what`` it is and its ``points`` [K,2] (x, y) in original photo pixels."""

    what: str
    points: np.ndarray


@dataclass
class PhotoLabels:
    """The marks of one photo: must-move and must-stay-still polygons."""

    name: str
    move: list[Polygon]
    still: list[Polygon]

    def masks(self, h: int, w: int, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """(move, still) bool [h, w] for a photo of original ``size`` (width, height) seen at w x h."""
        sx, sy = w / size[0], h / size[1]
        out = []
        for polys in (self.move, self.still):
            m = np.zeros((h, w), np.uint8)
            for p in polys:
                pts = np.round(p.points * [sx, sy]).astype(np.int32)
                cv2.fillPoly(m, [pts], 1)
            out.append(m.astype(bool))
        move, still = out
        return move & ~still, still & ~move  # a pixel marked both ways counts for nothing


@dataclass
class CaptureLabels:
    """All marks of one capture."""

    capture: str
    expects_motion: bool
    note: str
    photos: list[PhotoLabels]
    absent: tuple[str, ...] = ()  # effects whose kind the photos do not hold: choosing one is wrong


def _polys(items: list, where: str) -> list[Polygon]:
    out = []
    for i, it in enumerate(items):
        pts = np.asarray(it.get("points"), float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3:
            raise ValueError(f"{where}[{i}]: a polygon needs at least 3 [x, y] points, got {it.get('points')!r}")
        out.append(Polygon(str(it.get("what", "")), pts))
    return out


def load_labels(capture: str, folder: Path = LABELS) -> CaptureLabels:
    """The labels of ``capture`` (``folder/<capture>.json``); a malformed file is an error naming it."""
    path = Path(folder) / f"{capture}.json"
    if not path.exists():
        raise FileNotFoundError(f"{path}: no labels for capture {capture!r}")
    d = json.loads(path.read_text())
    photos = [PhotoLabels(name, _polys(v.get("move", []), f"{path}: {name} move"),
                          _polys(v.get("still", []), f"{path}: {name} still"))
              for name, v in d.get("photos", {}).items()]
    if len(photos) < 3:
        raise ValueError(f"{path}: {len(photos)} labelled photos, the benchmark needs at least 3")
    return CaptureLabels(d.get("capture", capture), bool(d.get("expects_motion", True)), d.get("note", ""), photos,
                         tuple(d.get("absent", ())))


def read_photo(path: Path) -> np.ndarray:
    """RGB uint8 [H,W,3] of a photo as a viewer shows it (EXIF orientation applied)."""
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise FileNotFoundError(f"{path}: not a readable photo")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def draw(img: np.ndarray, labels: PhotoLabels) -> np.ndarray:
    """RGB uint8 [H,W,3]: the photo with its must-move (green) and must-stay-still (red) polygons."""
    h, w = img.shape[:2]
    move, still = labels.masks(h, w, (w, h))
    out = img.astype(np.float32)
    out[move] = 0.55 * out[move] + 0.45 * np.array([40, 255, 60])
    out[still] = 0.55 * out[still] + 0.45 * np.array([255, 40, 40])
    out = out.astype(np.uint8)
    for polys, col in ((labels.move, (40, 255, 60)), (labels.still, (255, 40, 40))):
        for p in polys:
            pts = np.round(p.points).astype(np.int32)
            cv2.polylines(out, [pts], True, col, 1, cv2.LINE_AA)
            c = pts.mean(0).astype(int)
            cv2.putText(out, p.what, (int(c[0]) - 20, int(c[1])), cv2.FONT_HERSHEY_SIMPLEX, 0.4, col, 1, cv2.LINE_AA)
    return out


def sheet(captures: Path, capture: str, height: int = 360) -> np.ndarray:
    """RGB uint8: the capture's labelled photos side by side, each with its polygons drawn."""
    lab = load_labels(capture)
    tiles = []
    for p in lab.photos:
        img = draw(read_photo(Path(captures) / capture / p.name), p)
        s = height / img.shape[0]
        tiles.append(cv2.resize(img, (int(round(img.shape[1] * s)), height), interpolation=cv2.INTER_AREA))
    return np.hstack(tiles)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--captures", default=str(Path(__file__).resolve().parents[3] / "shared" / "captures"))
    ap.add_argument("--out", required=True)
    ap.add_argument("capture", nargs="*")
    a = ap.parse_args()
    names = a.capture or sorted(p.stem for p in LABELS.glob("*.json"))
    Path(a.out).mkdir(parents=True, exist_ok=True)
    for c in names:
        path = Path(a.out) / f"{c}.png"
        cv2.imwrite(str(path), cv2.cvtColor(sheet(Path(a.captures), c, 480), cv2.COLOR_RGB2BGR))
        print(path)


if __name__ == "__main__":
    main()
