"""What the static fit reached, what more accuracy would cost here, and whether it is good enough to
animate: the ``accuracy`` record of ``static/metrics.json`` (also logged, and drawn into
``static/fit.png`` for the Snakemake report).

Too poor to animate: held-out PSNR under :data:`MIN_TEST_PSNR` or train PSNR under
:data:`MIN_TRAIN_PSNR`. The thresholds sit in the gap between the shared captures whose final views
a person called smeared or blurred (held-out 13.8-20.3 dB, train 20.6-22.8 dB: the street walk,
the castle, the tree trunk at anigs 0.7's defaults) and those called sharp (25.6-30.3 dB and
26.6-31.9 dB: the flower, the fern, the indoor fox, the demo); benchmarks/README.md, "What the
static fit costs", has the table.
"""
from __future__ import annotations

import logging
import math
from typing import Any

from anigs.static.budget import CaptureSize, FitPlan, StepCost, next_level, plan

log = logging.getLogger("anigs.static.fit")

MIN_TEST_PSNR = 21.0  # dB, held out
MIN_TRAIN_PSNR = 24.0  # dB
REFERENCE = StepCost()  # one core's CPU seconds (benchmarks/README.md): deterministic minutes for artifacts
MAX_GAIN = 3.0  # dB: the most the curve's extrapolation promises (diminishing returns)
MIN_SIDE = 480  # px: the smallest photo size the advice suggests (about twice the default views' 256x192)
OVERFIT_GAP = 6.0  # train minus held-out PSNR (dB) above which more photos help more than a longer fit


def _extrapolate(curve: list[dict[str, Any]], steps: int) -> float | None:
    """Held-out PSNR at ``steps``: the gain per doubling of steps over the curve's last interval,
    carried on to ``steps`` and capped at :data:`MAX_GAIN` (None: fewer than two points)."""
    pts = [(r["iteration"], r["test_psnr"]) for r in curve if r["iteration"] > 0 and math.isfinite(r["test_psnr"])]
    pts = [p for i, p in enumerate(pts) if i == 0 or p[0] > pts[i - 1][0]]  # a re-evaluation at the same step
    if len(pts) < 2 or steps <= pts[-1][0]:
        return None
    (s0, p0), (s1, p1) = pts[-2], pts[-1]
    per_doubling = max(p1 - p0, 0.0) / math.log2(s1 / s0)
    return p1 + min(per_doubling * math.log2(steps / s1), MAX_GAIN)


def accuracy_record(metrics: dict[str, Any], fit_plan: FitPlan, size: CaptureSize, cost: StepCost,
                    start_gaussians: int) -> dict[str, Any]:
    """The ``accuracy`` record: now (held-out PSNR/SSIM, train PSNR, minutes), the next level (its
    plan and estimated minutes on this machine, the held-out PSNR the curve extrapolates to),
    and ``warning`` with the cheapest change that helps when the fit is too poor to animate."""
    now = {"test_psnr": metrics["test_psnr"], "test_ssim": metrics["test_ssim"], "train_psnr": metrics["train_psnr"],
           "minutes": round(metrics["train_seconds"] / 60.0, 2), "level": fit_plan.level,
           "gaussians": metrics["num_gaussians"], "steps": metrics["iterations"]}
    rec: dict[str, Any] = {"now": now, "thresholds": {"test_psnr": MIN_TEST_PSNR, "train_psnr": MIN_TRAIN_PSNR}}
    nxt = next_level(fit_plan.level)
    if nxt is not None:
        p = plan(nxt, size, cost, start_gaussians)
        est = _extrapolate(metrics.get("curve", []), p.iterations)
        ref = plan(nxt, size, REFERENCE, start_gaussians)
        rec["next"] = {"level": nxt, "steps": p.iterations, "gaussians": p.max_gaussians,
                       "estimated_minutes": round(p.estimated_seconds / 60.0, 1),
                       "reference_cpu_minutes": round(ref.estimated_seconds / 60.0, 1),
                       "test_psnr_from_curve": None if est is None else round(est, 2),
                       "note": "test_psnr_from_curve: the gain per doubling of steps over the held-out curve's last "
                               f"interval, carried on to the next level's steps (at most +{MAX_GAIN:g} dB); more "
                               "Gaussians and a larger image size change it further"}
    # the warning is an artifact's text (final.json, the effects overview): its minutes come from the
    # reference cost model, not this machine's timing, so the same config gives the same bytes
    rec["warning"] = _warning(metrics, fit_plan, size, REFERENCE, start_gaussians)
    return rec


def _warning(metrics: dict[str, Any], fit_plan: FitPlan, size: CaptureSize, cost: StepCost,
             start_gaussians: int) -> str | None:
    """None when the fit is good enough to animate, else what is wrong and the cheapest change that helps."""
    test, train = metrics["test_psnr"], metrics["train_psnr"]
    low_test = math.isfinite(test) and test < MIN_TEST_PSNR
    if not (low_test or train < MIN_TRAIN_PSNR):
        return None
    low = [f"held-out PSNR {test:.1f} dB (under {MIN_TEST_PSNR:g}: smeared views)" if low_test else "",
           f"train PSNR {train:.1f} dB (under {MIN_TRAIN_PSNR:g})" if train < MIN_TRAIN_PSNR else ""]
    what = "the static fit is too blurry to animate: " + " and ".join(x for x in low if x)
    if low_test and train - test > OVERFIT_GAP:  # the street walk: held-out flat while the Gaussians grew 5x
        return (f"{what}; it fits the photos {train - test:.0f} dB better than the photos it did not train on: the "
                "capture sees each part from too few places, and more photos between the existing ones help "
                "most (a denser walk, 60-80% overlap between neighbours); a longer fit sharpens the photos' own "
                "views only")
    options = []
    nxt = next_level(fit_plan.level)
    if nxt is not None:
        p = plan(nxt, size, cost, start_gaussians)
        options.append((p.estimated_seconds, f"static.budget: {nxt} ({p.iterations} steps, {p.max_gaussians:,} "
                                             f"Gaussians, about {p.estimated_seconds / 60:.0f} CPU min)"))
    side = max(size.limited(fit_plan.max_side).width, size.limited(fit_plan.max_side).height)
    if side > MIN_SIDE:  # a smaller image size (not below MIN_SIDE): the next level on fewer pixels
        smaller = max(MIN_SIDE, side // 2)
        p = plan(fit_plan.level if nxt is None else nxt, size, cost, start_gaussians, max_side=smaller)
        options.append((p.estimated_seconds, f"static.max_side: {smaller} with static.budget: {p.level} "
                                             f"(about {p.estimated_seconds / 60:.0f} CPU min)"))
    if not options:
        return f"{what}; more photos of the scene are the remaining remedy"
    options.sort()
    return f"{what}; the cheapest change that helps: {options[0][1]}" + (
        f"; or {options[1][1]}" if len(options) > 1 else "")


def held_out_text(psnr: float | None, ssim: float | None) -> str:
    """The held-out PSNR and SSIM in words, or that no photo was held out (``static.holdout_every: 0``)."""
    if psnr is None or not math.isfinite(psnr):
        return "no held-out photos (static.holdout_every: 0)"
    return f"held-out PSNR {psnr:.2f} dB, SSIM {ssim:.3f}"


def draw_fit(metrics: dict[str, Any], path) -> None:
    """``static/fit.png``: held-out PSNR against the steps (points labelled by the Gaussian count) and
    the accuracy record in words (the plan, now, the next level, the warning). Only what the same
    config and seed reproduce is drawn: this machine's seconds are in metrics.json and the log."""
    import textwrap

    import cv2
    import numpy as np

    from anigs.io import atomic_path
    from anigs.knob_chart import knob_image

    checkpoints = metrics.get("curve", [])
    rows = [{"knob": "fit", "seconds": r["iteration"], "test_psnr": r["test_psnr"],
             "value": f"{r['num_gaussians'] / 1000:.0f}k"} for r in checkpoints
            if r["test_psnr"] is not None and math.isfinite(r["test_psnr"])]
    if rows:
        plot = knob_image(rows, "fit", ["test_psnr"], panel=(640, 300), x_label="steps (labels: Gaussians)")
    else:  # no held-out photos: the Gaussians the fit grew
        rows = [{"knob": "fit", "seconds": r["iteration"], "num_gaussians": r["num_gaussians"], "value": ""}
                for r in checkpoints]
        plot = knob_image(rows, "fit", ["num_gaussians"], panel=(640, 300), x_label="steps (no held-out photos)")
    acc, pl = metrics.get("accuracy", {}), metrics.get("plan", {})
    now = acc.get("now", {})
    flat = " (the held-out curve flattened)" if pl.get("stopped_early") else ""
    lines = [f"budget {pl.get('level')}: {now.get('steps')} of {pl.get('iterations')} steps{flat}, "
             f"{now.get('gaussians', 0):,} of {pl.get('max_gaussians', 0):,} Gaussians",
             f"now: {held_out_text(now.get('test_psnr'), now.get('test_ssim'))}; "
             f"train PSNR {now.get('train_psnr', float('nan')):.2f} dB"]
    nxt = acc.get("next")
    if nxt:
        curve = ("" if nxt.get("test_psnr_from_curve") is None
                 else f"; the curve points to {nxt['test_psnr_from_curve']:.1f} dB")
        lines.append(f"next level {nxt['level']}: {nxt['steps']} steps, {nxt['gaussians']:,} Gaussians, about "
                     f"{nxt['reference_cpu_minutes']:.0f} CPU min{curve} (minutes on this machine: metrics.json)")
    text = [(ln, (0, 0, 0)) for ln in lines]
    if acc.get("warning"):
        text += [(ln, (0, 0, 190)) for ln in textwrap.wrap("WARNING: " + acc["warning"], 100)]
    block = np.full((18 * len(text) + 10, plot.shape[1], 3), 255, np.uint8)
    for i, (ln, ink) in enumerate(text):
        cv2.putText(block, ln, (8, 18 * (i + 1)), cv2.FONT_HERSHEY_SIMPLEX, 0.42, ink, 1, cv2.LINE_AA)
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), np.concatenate([plot, block], 0)):
            raise OSError(f"could not write {path}")


def log_accuracy(acc: dict[str, Any]) -> dict[str, Any]:
    """Log what the next level would cost and reach, and the warning; returns ``acc``."""
    nxt = acc.get("next")
    if nxt:
        log.info("the next level, %s (%d steps, %d Gaussians), would take about %.0f min here%s", nxt["level"],
                 nxt["steps"], nxt["gaussians"], nxt["estimated_minutes"], "" if nxt["test_psnr_from_curve"] is None
                 else f"; the held-out curve extrapolates to {nxt['test_psnr_from_curve']:.1f} dB with its steps")
    if acc["warning"]:
        log.warning("%s", acc["warning"])
    return acc
