"""Which knobs of the effects stage's rules and decision move a figure of the labelled benchmark (issue 49, item 4).

    nice -n 10 python benchmarks/knob_sensitivity.py [--seeds 0 1 2] [--capture NAME ...] [--decoy-seeds 0 1 2]
        [--fits /work/scratch/seeds] [--out /work/scratch/knobs] [--knob KEY ...] [--no-decoys] [--no-check] [--no-memo]

Per cached fit (``--fits/seed-K/<capture>``: ``sfm/``, ``static/``) the stage runs once up to and including
``lift`` at the defaults (per set of regions looked for); the baseline and each variant (one knob at a time)
run only ``apply_rules``, ``decide`` and the choice, and each phrasing is scored as ``real_captures.py`` does:
chosen effects, recall (and the blossoms'), pooled and worst still mark's moving share, verdict. No earlier step
reads a ``rules.*``/``decide.*`` knob but ``rules.blossoms.with_plants`` (the regions looked for: its variant
reruns ``photo regions`` and ``lift``); the baseline is checked against a full ``decide_effects`` run. Renders
and rule verdicts that repeat are memoised exactly (``--no-memo`` runs them all). Variants: float x at 0.5x and
1.5x (fractions clamped to 1; a zero default at 0.1 and 0.35), int x-1/x+1 (half/double above 4), bool flipped.
The decoys (``anigs.synth.decoys``, ``made_decoys``) go through the same sweep, scored on their labels as
``tests/effects/test_decoys.py`` and ``test_made_decoys.py`` do. Writes ``--out/knob_sensitivity.{md,json}``.
"""
from __future__ import annotations

import argparse
import copy
import dataclasses
import hashlib
import json
import sys
import time
from collections import OrderedDict
from pathlib import Path

import cv2  # noqa: F401  (before pycolmap, which the stage imports)
import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
import anigs.effects.config as effects_config  # noqa: E402
from anigs.effects import detect, outline  # noqa: E402
from anigs.effects.choice import choose, decide_effects  # noqa: E402
from anigs.effects.kinds import REGIONS  # noqa: E402
from anigs.effects.rules import TABLE  # noqa: E402
from anigs.effects.vocabulary import prompt_kinds  # noqa: E402
from anigs.cameras import load_cameras  # noqa: E402
from anigs.gaussians import load_ply  # noqa: E402
from anigs.stages.effects import analysed_photos  # noqa: E402
from anigs.synth import LABEL_IDS, render_image  # noqa: E402
from anigs.synth.decoys import ALLOWED, DECOY_PARTS, DECOYS, MADE_DECOYS, build_decoy  # noqa: E402
from real_captures import (SCENES, default_captures, moving_of, nested, phrasings, photo_sizes, score,  # noqa: E402
                           verdict)
from real.labels import load_labels  # noqa: E402

EffectsConfig = getattr(effects_config, "EffectsConfig", None) or effects_config.Config
FRACTION = ("share", "fraction", "saturation", "value", "cos", "agree", "smooth", "in_crown", "above")
FIGURES = ("chosen", "recall", "blossoms", "still", "worst_still", "worst_what", "verdict")


def knob_variants() -> list[dict]:
    """Every knob of ``rules`` and ``decide`` with its variants: [{knob, default, value, note}]."""
    def knobs(prefix: str, sec) -> list:
        return [y for f in dataclasses.fields(sec) for y in (knobs(f"{prefix}.{f.name}", getattr(sec, f.name))
                if dataclasses.is_dataclass(getattr(sec, f.name)) else [(f"{prefix}.{f.name}", getattr(sec, f.name))])]
    out = []
    for key, x in knobs("rules", EffectsConfig().rules) + knobs("decide", EffectsConfig().decide):
        if isinstance(x, bool):
            values = [(not x, "flipped")]
        elif isinstance(x, int):
            values = [(x - 1, "x-1"), (x + 1, "x+1")] if x <= 4 else [(x // 2, "half"), (2 * x, "double")]
        elif isinstance(x, float) and x == 0:
            values = [(0.1, "zero default: 0.1"), (0.35, "zero default: 0.35")]
        else:  # a float (every knob of these sections is a number or a bool)
            top = 1.0 if any(w in key.rsplit(".", 1)[-1] for w in FRACTION) else float("inf")
            values = [(x * 0.5, "0.5x"), (min(x * 1.5, top), "1.5x" if x * 1.5 <= top else "1.5x clamped to 1")]
        for value, note in values:
            value, note = _valid(key, x, round(value, 6) if isinstance(value, float) else value, note)
            out.append({"knob": key, "default": x, "value": value, "note": note})
    return out


def _valid(key: str, x, value, note: str):
    """``value``, or halfway back towards the default while the section's validation rejects it."""
    for _ in range(4):
        try:
            return make_cfg(key, value) and value, note
        except ValueError:
            value, note = type(x)((value + x) / 2), note + "; rejected, stepped halfway back"
    raise ValueError(f"{key}: no valid variant near {x}")


def make_cfg(key: str | None = None, value=None):
    """The default effects config with ``key`` (dotted, from the section's root) set to ``value``."""
    return EffectsConfig() if key is None else EffectsConfig.from_dict(nested({key: value}))


def _digest(a) -> str:
    return "" if a is None else hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest()


class Memo:
    """Exact memoisation of the costly pure calls the variants repeat (one scene at a time): a render of the same
    features at the same camera of the same Gaussians, and a rule's verdict (and the figures it notes) on the same
    candidate in the same context with the same knobs. ``on`` False: every call runs."""

    def __init__(self, size: int = 800, on: bool = True):
        self.renders, self.verdicts, self.size, self.on = OrderedDict(), {}, size, on
        render = detect.render_features

        def cached_render(g, features, cam):
            f = np.asarray(features, np.float32)
            key = (id(g), id(cam), _digest(f), f.shape)
            hit = self.renders.get(key) if self.on else None
            if hit is not None and hit[0] is g and hit[1] is cam:
                self.renders.move_to_end(key)
                return hit[2]
            out = render(g, f, cam)
            if self.on:
                self.renders[key] = (g, cam, out)
                if len(self.renders) > self.size:
                    self.renders.popitem(last=False)
            return out
        detect.render_features = outline.render_features = cached_render
        for cls in {c for row in TABLE.values() for c in row}:
            cls.check = self._rule(cls.check)

    def _rule(self, check):
        def cached(rule, cand, ctx):
            if not self.on:
                return check(rule, cand, ctx)
            if getattr(ctx, "memo_key", None) is None:
                ctx.memo_key = (_digest(ctx.region_of), ctx.link, ctx.radius, ctx.cam_height, ctx.blossoms_of,
                                ctx.unasked, ctx.seed)
            key = (type(rule).__name__, dataclasses.astuple(rule), cand.region, _digest(cand.indices),
                   repr(sorted(cand.figures.items())), ctx.memo_key, _digest(ctx.bearers))
            if key not in self.verdicts:
                self.verdicts[key] = (check(rule, cand, ctx), dict(cand.figures))
            cand.figures = dict(self.verdicts[key][1])
            return self.verdicts[key][0]
        return cached

    def clear(self) -> None:  # a new scene
        self.renders, self.verdicts = OrderedDict(), {}


@dataclasses.dataclass
class Scene:
    """A scene's state after the steps before ``rules``: Gaussians, analysed photos' cues and, per set of
    regions looked for, the lifted regions."""

    g: object
    cues: object
    lifted: dict = dataclasses.field(default_factory=dict)  # tuple(wanted) -> (regions, region_of, share)

    @classmethod
    def build(cls, images, cameras, g, cfg=EffectsConfig()) -> "Scene":
        photos, cams = detect.prepare_photos(images, cameras, cfg.photos)
        return cls(h := g.detach(), detect.scene_cues(h, photos, cams, cfg.cues, cfg.photos.min_alpha))

    def lift(self, cfg, wanted: list[str]):
        key = tuple(wanted)
        if key not in self.lifted:  # photo regions and lift read no rules.* or decide.* knob
            regions, _ = detect.photo_regions(self.cues, cfg, wanted)
            self.lifted[key] = (regions, *detect.lift(self.g, self.cues, regions, cfg.lift))
        return self.lifted[key]

    def after_lift(self, cfg, kinds):
        """``apply_rules``, ``decide`` and the result, as :func:`detect.detect_effects` runs them."""
        kinds, blossoms_of, wanted = detect.looked_for(kinds, cfg)
        regions, region_of, share = self.lift(cfg, wanted)
        regions = copy.deepcopy(regions)  # apply_rules edits the masks
        ruled = detect.apply_rules(self.g, self.cues, region_of.copy(), regions, cfg, blossoms_of)
        for reg in regions if blossoms_of else ():  # as detect_effects: no flowers region of their own
            reg.masks["flowers"] = np.zeros_like(reg.masks["flowers"])
        effects = detect.decide(self.g, self.cues, regions, ruled, share, cfg, kinds, blossoms_of, None)
        return detect.EffectsResult(effects, [], [p.camera for p in self.cues.maps], ruled.region_of,
                                    self.cues.ground, cfg, ruled.candidates, ruled.rejected_masks, ruled.fragments)


@dataclasses.dataclass
class Cell:
    """One scored case: a capture (or decoy), seed and phrasing; ``kinds`` None: every region."""

    name: str
    scene: Scene
    kinds: list | None
    named: list | None
    scorer: object  # (chosen, dynamic [N], region_of [N]) -> figures
    check: tuple | None = None  # (photos, cameras, Gaussians, prompt): for a full decide_effects run


def real_cells(capture: str, seed: int, fits: Path, captures: Path) -> list[Cell]:
    """The phrasings of ``capture`` on the fit of ``seed``."""
    folder = fits / f"seed-{seed}" / capture
    g = load_ply(folder / "static" / "canonical.ply")
    all_cams = load_cameras(folder / "sfm" / "cameras.json")
    photos, cams = analysed_photos(folder / "sfm" / "images", all_cams, EffectsConfig())
    scene = Scene.build(photos, cams, g)
    labels = load_labels(capture)
    sizes = photo_sizes(captures, capture, labels)
    by_stem = {Path(c.name).stem: c for c in all_cams}
    names = [p.name for p in labels.photos]
    maps: dict = {}

    def scorer(expect):
        def run(chosen, dyn, reg):
            key = _digest(dyn) + _digest(reg[dyn])
            sc = maps[key] = maps.get(key) or score(labels, moving_of(g, dyn, reg, by_stem, names), sizes)
            return {"chosen": list(chosen), **{k: sc[k] for k in FIGURES[1:6]},
                    "verdict": verdict(expect, sc, list(chosen), labels.absent)}
        return run

    out = []
    for ph in phrasings(capture):
        k = prompt_kinds(ph["prompt"])
        out.append(Cell(f"{capture}/seed-{seed}/{ph['kind']}", scene, list(k.regions), list(k.effects),
                        scorer(ph["expect"]), (photos, cams, g, ph["prompt"])))
    return out


def decoy_cell(name: str, seed: int) -> Cell:
    """A decoy scene as its test runs it: no prompt (``DECOYS``) or its prompt (``MADE_DECOYS``)."""
    d = build_decoy(name, seed=seed)
    scene = Scene.build(imgs := [render_image(d.gaussians, c) for c in d.cameras], d.cameras, d.gaussians)
    kinds = prompt_kinds(d.prompt) if name in MADE_DECOYS else None
    labels, part = d.gaussians.extras["label"].numpy(), d.gaussians.extras["decoy"].numpy()
    region = {"foliage_sway": "foliage", "leaf_flutter": "foliage", "grass_wave": "grass", "flower_bob": "flowers"}
    truth = np.isin(labels, [LABEL_IDS[region[e]] for e in d.effects])
    still = d.still_mask()

    def run(chosen, dyn, reg):
        worst = max([(float((dyn & (part == k) & ~np.isin(reg, [REGIONS.index(region[e]) for e in ALLOWED[what]]))
                            .sum() / (part == k).sum()), what)  # the pot's blurred rim is tolerated (as its test)
                     for k, what in DECOY_PARTS.items() if (part == k).any() and what != "pot"] + [(0.0, "")])
        worst = worst if worst[0] > 0 else (0.0, "")
        rec = float(dyn[truth].mean()) if truth.any() else None
        st = float((dyn & still).sum() / max(dyn.sum(), 1))
        bad = [f"missing {e}" for e in d.effects if e not in chosen] + ["chose flower_bob"] * (
            "flower_bob" in chosen and "flower_bob" not in d.effects) + ["still part"] * (worst[0] > 0)
        bad += ["still share"] * (st > 0.03) + ["recall"] * (rec is not None and rec < 0.8)
        return {"chosen": list(chosen), "recall": rec, "blossoms": None, "still": st, "worst_still": worst[0],
                "worst_what": worst[1], "verdict": "ok" if not bad else "FAIL: " + ", ".join(bad)}

    return Cell(f"decoy:{name}/seed-{seed}", scene, None if kinds is None else list(kinds.regions),
                None if kinds is None else list(kinds.effects), run,
                (imgs, d.cameras, d.gaussians, d.prompt if kinds is not None else None))


def figures(cells: list[Cell], cfg) -> dict[str, dict]:
    """Every cell's figures under ``cfg``: rules and decision once per scene and regions looked for."""
    done: dict = {}
    out = {}
    for c in cells:
        key = (id(c.scene), None if c.kinds is None else tuple(c.kinds))
        if key not in done:
            done[key] = c.scene.after_lift(cfg, c.kinds)
        res = done[key]
        chosen, _ = choose(res.detected, "auto", c.named)
        out[c.name] = c.scorer(chosen, res.dynamic(chosen), res.region_of.astype(np.int8))
    return out


def check_baseline(cell: Cell, base: dict) -> None:
    """The baseline figures of ``cell`` equal a full ``decide_effects`` run's (the stage's detection)."""
    photos, cams, g, prompt = cell.check
    MEMO.on, on = False, MEMO.on
    dec = decide_effects(photos, cams, g, EffectsConfig(prompt=prompt), "auto")
    MEMO.on = on
    full = cell.scorer(dec.report["chosen"], dec.dynamic, dec.result.region_of.astype(np.int8))
    if full != base[cell.name]:
        raise SystemExit(f"{cell.name}: the baseline differs from a full run: {base[cell.name]} != {full}")
    print(f"check: {cell.name} ({prompt!r}): a full decide_effects run gives the baseline's {full}", flush=True)


def sweep(cells: list[Cell], variants: list[dict], runs: list[dict], check: bool) -> None:
    """The baseline and every variant on ``cells`` (one scene); appends {knob, value, cell, figures} to ``runs``."""
    MEMO.clear()
    t0 = time.perf_counter()
    base = figures(cells, make_cfg())
    print(f"{cells[0].name.rsplit('/', 1)[0]}: lift and baseline in {time.perf_counter() - t0:.0f} s", flush=True)
    if check and cells[0].check is not None:
        check_baseline(cells[0], base)
    t0 = time.perf_counter()
    runs += [{"knob": None, "value": None, "cell": n, **f} for n, f in base.items()]
    for v in variants:
        for n, f in figures(cells, make_cfg(v["knob"], v["value"])).items():
            runs.append({"knob": v["knob"], "value": v["value"], "cell": n, **f})
    s = time.perf_counter() - t0
    print(f"{cells[0].name.rsplit('/', 1)[0]}: {len(cells)} cells x {len(variants)} variants in {s:.0f} s "
          f"({s / max(len(variants), 1):.1f} s a variant)", flush=True)


def _delta(a, b) -> float:
    return 0.0 if a is None and b is None else 1.0 if a is None or b is None else abs(a - b)


def summarise(runs: list[dict], variants: list[dict]) -> list[dict]:
    """Per variant: real and decoy cells changed, largest recall and worst-still changes, the changed cells."""
    base = {r["cell"]: r for r in runs if r["knob"] is None}
    rows = []
    for v in variants:
        mine = [r for r in runs if r["knob"] == v["knob"] and r["value"] == v["value"]]
        moved = [r for r in mine if any(r[f] != base[r["cell"]][f] for f in FIGURES)]
        real = [r for r in moved if not r["cell"].startswith("decoy:")]
        rows.append({**v, "cells": sum(not r["cell"].startswith("decoy:") for r in mine), "changed": len(real),
                     "decoys": len(moved) - len(real), "changed_cells": sorted(r["cell"] for r in moved),
                     "d_recall": max([_delta(r["recall"], base[r["cell"]]["recall"]) for r in real], default=0.0),
                     "d_still": max([_delta(r["worst_still"], base[r["cell"]]["worst_still"]) for r in real],
                                    default=0.0),
                     "verdicts": sum(r["verdict"] != base[r["cell"]]["verdict"] for r in real)})
    return rows


def merge_candidates(rows: list[dict], runs: list[dict]) -> list[tuple[str, str, bool]]:
    """Pairs of knobs that change something, in the same cells per variant (low with low and high with high, or
    crossed); with whether those cells' figures are the same too."""
    figs: dict = {}
    for r in runs:
        figs.setdefault((r["knob"], json.dumps(r["value"])), {})[r["cell"]] = json.dumps([r[f] for f in FIGURES])
    per: dict = {}
    for r in rows:
        per.setdefault(r["knob"], []).append((set(r["changed_cells"]), figs[(r["knob"], json.dumps(r["value"]))]))
    live = [k for k, p in per.items() if any(c for c, _ in p)]
    out = []
    for i, a in enumerate(live):
        for b in live[i + 1:]:
            for pb in (per[b], per[b][::-1]):
                if len(per[a]) == len(pb) and all(x[0] == y[0] for x, y in zip(per[a], pb)):
                    out.append((a, b, all(x[1] == y[1] for x, y in zip(per[a], pb))))
                    break
    return out


def report(rows: list[dict], merges: list, seeds: list[int], decoy_seeds: list[int], wall: float, cmd: str) -> str:
    """The markdown report."""
    lines = ["# Knob sensitivity of the effects stage's rules and decision (issue 49, item 4)\n",
             f"Fits: seeds {seeds}; decoys: seeds {decoy_seeds}. Reproduce: `{cmd}`. Wall time {wall / 60:.1f} min.\n",
             "A cell is one (capture, seed, phrasing); a cell changed when any figure (chosen effects, recall, "
             "blossoms recall, pooled still share, worst still mark's share or name, verdict) differs from the "
             "defaults'.\n",
             "| knob | default | variant | cells changed | verdicts changed | largest recall change | "
             "largest worst-still change | decoy cells changed |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| `{r['knob']}` | {r['default']!r} | {r['value']!r} ({r['note']}) | {r['changed']}/{r['cells']} "
                     f"| {r['verdicts']} | {r['d_recall']:.4f} | {r['d_still']:.4f} | {r['decoys']} |")
    knobs = list(dict.fromkeys(r["knob"] for r in rows))
    idle = [k for k in knobs if not any(r["changed"] for r in rows if r["knob"] == k)]
    lines += ["\n## Knobs that changed no real-capture figure\n"]
    for k in idle:
        dec = sorted({c for r in rows if r["knob"] == k for c in r["changed_cells"]})
        lines.append(f"- `{k}`: " + (f"changes decoy cells: {', '.join(dec)}" if dec else "changes nothing anywhere"))
    lines += ["\n## Merge candidates: knobs whose changed cells are the same, per direction\n"]
    lines += [f"- `{a}` and `{b}`: " + ("the same figures in every cell" if same else "the same cells, other figures")
              for a, b, same in merges] or ["- none"]
    return "\n".join(lines) + "\n"


MEMO: Memo | None = None  # main's: patches the renders and the rules' checks of this process


def main() -> None:
    global MEMO
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fits", type=Path, default=Path("/work/scratch/seeds"))
    ap.add_argument("--captures", type=Path, default=default_captures())
    ap.add_argument("--capture", nargs="*", default=None)
    ap.add_argument("--seeds", nargs="*", type=int, default=[0, 1, 2])
    ap.add_argument("--decoy-seeds", nargs="*", type=int, default=[0, 1, 2])
    ap.add_argument("--out", type=Path, default=Path("/work/scratch/knobs"))
    ap.add_argument("--no-decoys", action="store_true")
    ap.add_argument("--no-check", action="store_true", help="skip the full decide_effects run checking the baseline")
    ap.add_argument("--knob", nargs="*", default=None, help="only these knobs (default all)")
    ap.add_argument("--no-memo", action="store_true", help="run every render and rule check (to check the memo)")
    a = ap.parse_args()
    MEMO = Memo(on=not a.no_memo)
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    variants = [v for v in knob_variants() if a.knob is None or v["knob"] in a.knob]
    runs: list[dict] = []
    jobs = [(lambda c=c, s=s: real_cells(c, s, a.fits, a.captures))
            for c in a.capture or sorted(p.stem for p in SCENES.glob("*.yaml")) for s in a.seeds]
    jobs += [] if a.no_decoys else [(lambda n=n, s=s: [decoy_cell(n, s)]) for n in DECOYS + MADE_DECOYS
                                    for s in a.decoy_seeds]
    a.out.mkdir(parents=True, exist_ok=True)
    for i, job in enumerate(jobs):
        t1 = time.perf_counter()
        cells = job()
        print(f"{cells[0].name.rsplit('/', 1)[0]}: photos and cues in {time.perf_counter() - t1:.0f} s", flush=True)
        sweep(cells, variants, runs, not a.no_check and i in (0, len(jobs) - 1))  # the first fit, the last decoy
        (a.out / "partial.json").write_text(json.dumps(runs, default=str))  # what is done, should the run stop
    rows = summarise(runs, variants)
    wall = time.perf_counter() - t0
    cmd = "nice -n 10 python " + " ".join([str(Path(sys.argv[0])), *sys.argv[1:]])
    text = report(rows, merge_candidates(rows, runs), a.seeds, [] if a.no_decoys else a.decoy_seeds, wall, cmd)
    print(text)
    (a.out / "knob_sensitivity.md").write_text(text)
    (a.out / "knob_sensitivity.json").write_text(json.dumps({"variants": rows, "runs": runs, "wall_s": wall,
                                                             "command": cmd}, indent=1, default=str))
    print(f"wall time {wall:.0f} s ({wall / 60:.1f} min)")


if __name__ == "__main__":
    main()
