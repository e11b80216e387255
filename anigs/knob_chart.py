"""Charts of metrics against one setting (a knob): one PNG per knob, for the accuracy-versus-time
sweep (:mod:`anigs.reports.tradeoff`) and the static fit's report (:mod:`anigs.static.report`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np
from anigs.io import atomic_path


def plot_knob(rows: Sequence[dict[str, Any]], knob: str, metric_names: Sequence[str], path: str | Path,
              panel: tuple[int, int] = (360, 260), fronts: dict[str, list[int]] | None = None) -> Path:
    """PNG with one panel per metric: metric (y) against seconds (x), points labelled by value.

    ``fronts`` (:func:`anigs.reports.tradeoff.report_fronts`: metric -> indices into ``rows``): each panel also draws its
    metric's Pareto front over every point as a green line, rings this knob's points on it, and
    marks the other knobs' front points with small hollow squares.
    """
    import cv2


    img = knob_image(rows, knob, metric_names, panel, fronts)
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), img):
            raise OSError(f"could not write {path}")
    return Path(path)


def knob_image(rows: Sequence[dict[str, Any]], knob: str, metric_names: Sequence[str],
               panel: tuple[int, int] = (360, 260), fronts: dict[str, list[int]] | None = None,
               x_label: str = "seconds") -> np.ndarray:
    """The picture of :func:`plot_knob` as a BGR uint8 array [H,W,3] (``x_label``: the x axis' name)."""
    import cv2

    sel = sorted((r for r in rows if r["knob"] == knob), key=lambda r: r["seconds"])
    names = [m for m in metric_names if any(r.get(m) is not None for r in sel)] or ["seconds"]
    pw, ph = panel
    img = np.full((ph, pw * len(names), 3), 255, np.uint8)
    font, L, B, T, Rm = cv2.FONT_HERSHEY_SIMPLEX, 58, 42, 30, 14
    for i, m in enumerate(names):
        x0 = i * pw
        pts = [(r["seconds"], r.get(m), r["value"]) for r in sel if r.get(m) is not None]
        front = [rows[j] for j in (fronts or {}).get(m, [])]
        on_front = {id(r) for r in front}
        fpts = [(r["seconds"], r[m]) for r in front]
        cv2.putText(img, f"{m} vs {x_label}", (x0 + 8, 18), font, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.rectangle(img, (x0 + L, T), (x0 + pw - Rm, ph - B), (0, 0, 0), 1)
        if not pts:
            continue
        xs = np.array([p[0] for p in pts] + [p[0] for p in fpts], float)
        ys = np.array([p[1] for p in pts] + [p[1] for p in fpts], float)
        xlo, xhi = xs.min(), xs.max()
        ylo, yhi = ys.min(), ys.max()
        xpad = (xhi - xlo) * 0.1 or max(abs(xhi) * 0.1, 1.0)
        ypad = (yhi - ylo) * 0.1 or max(abs(yhi) * 0.1, 1e-6)
        xlo, xhi, ylo, yhi = xlo - xpad, xhi + xpad, ylo - ypad, yhi + ypad

        def to_px(x: float, y: float) -> tuple[int, int]:
            u = x0 + L + (x - xlo) / (xhi - xlo) * (pw - L - Rm)
            v = ph - B - (y - ylo) / (yhi - ylo) * (ph - B - T)
            return int(round(u)), int(round(v))

        for frac in (0.0, 1.0):
            xv, yv = xlo + frac * (xhi - xlo), ylo + frac * (yhi - ylo)
            cv2.putText(img, f"{xv:.0f}", (to_px(xv, ylo)[0] - 10, ph - B + 14), font, 0.35, (60, 60, 60), 1)
            cv2.putText(img, f"{yv:.3g}", (x0 + 2, to_px(xlo, yv)[1] + 4), font, 0.33, (60, 60, 60), 1)
        cv2.putText(img, x_label, (x0 + pw // 2 - 20, ph - 8), font, 0.38, (0, 0, 0), 1, cv2.LINE_AA)
        green = (40, 150, 40)
        fpx = [to_px(x, y) for x, y in fpts]
        if fpx:
            cv2.putText(img, "front", (x0 + pw - Rm - 40, ph - 8), font, 0.38, green, 1, cv2.LINE_AA)
        for a, b in zip(fpx[:-1], fpx[1:]):
            cv2.line(img, a, b, green, 2, cv2.LINE_AA)
        for r, (u, v) in zip(front, fpx):
            if r["knob"] != knob:
                cv2.rectangle(img, (u - 3, v - 3), (u + 3, v + 3), green, 1, cv2.LINE_AA)
        px = [to_px(x, y) for x, y, _ in pts]
        for a, b in zip(px[:-1], px[1:]):
            cv2.line(img, a, b, (180, 120, 40), 1, cv2.LINE_AA)
        mine = [r for r in sel if r.get(m) is not None]
        for (u, v), (_, _, val), r in zip(px, pts, mine):
            cv2.circle(img, (u, v), 4, (180, 80, 20), -1, cv2.LINE_AA)
            if id(r) in on_front:
                cv2.circle(img, (u, v), 7, green, 2, cv2.LINE_AA)
            cv2.putText(img, str(val), (u + 5, v - 5), font, 0.35, (20, 20, 160), 1, cv2.LINE_AA)
    return img
