"""Made things stay still whatever their colour (issue 47): the made-thing decoys of
:mod:`anigs.synth.made_decoys` under prompts that name plants, on three scene seeds.

- ``yard`` ("a castle courtyard with trees in the wind"): a green tractor and green wheelie bins on
  paving before two facades, a leafless tree; no ground plane is found (the paving is 1.3% of the
  Gaussians). Nothing may move.
- ``hall`` ("an office with potted plants"): smooth green pillars, a carton printed with leaves on a
  table, a real potted plant; the floor is mostly out of view and no ground plane is found. The
  pillars, the carton, the table and the floor stay still; the plant's leaves sway (recall >= 0.8).

The detector runs as the effects stage runs it (:func:`anigs.effects.choice.decide_effects` with the
decoy's prompt: only the kinds it names are looked for, and flowers as the named plants' blossoms);
the fitted model is the scene itself. On 0.13.0 the still checks fail on every seed: the tractor, the
bins, the pillars and the carton are chosen as foliage (the only foliage rule, ``plane``, keeps them:
under 60% of them on large planes, or rising off them), and the blossoms rule moves the orange table,
parts of the carton and the terracotta pot with the "plants"; the plant itself moves (recall 0.99).
"""
from __future__ import annotations

from functools import lru_cache

import pytest

from anigs.effects import EffectsConfig
from anigs.effects.choice import decide_effects
from anigs.synth import LABEL_IDS, render_image
from anigs.synth.decoys import DECOY_PARTS, MADE_DECOYS, build_decoy

SEEDS = (0, 1, 2)
CASES = [(n, s) for n in MADE_DECOYS for s in SEEDS]
TOLERATED = ("pot",)  # the plant's pot joins the still share below, not the per-part check (blurred rim)


@lru_cache(maxsize=None)
def _staged(name: str, seed: int):
    """The decoy and the effects stage's decision on it (once per scene and seed)."""
    d = build_decoy(name, seed=seed)
    imgs = [render_image(d.gaussians, c) for c in d.cameras]
    return d, decide_effects(imgs, d.cameras, d.gaussians, EffectsConfig(prompt=d.prompt), "auto")


def _report(d, dec) -> dict[str, tuple[int, int, str]]:
    """Per decoy part: (its moving Gaussians, its Gaussians, the candidates that let it move: number, region,
    rule)."""
    part = d.gaussians.extras["decoy"].numpy()
    out = {}
    for k, name in DECOY_PARTS.items():
        inside = part == k
        if not inside.any():
            continue
        moved = dec.dynamic & inside
        why = sorted({f"#{c.number} {c.region}{'->' + c.moved_to if c.moved_to else ''} ({c.rule or 'kept'})"
                      for c in dec.result.candidates if (c.kept or c.moved_to) and moved[c.indices].any()})
        out[name] = (int(moved.sum()), int(inside.sum()), ", ".join(why))
    return out


@pytest.mark.parametrize("name,seed", CASES)
def test_the_prompt_decides_what_is_looked_for(name: str, seed: int):
    d, dec = _staged(name, seed)
    assert dec.report["prompt"]["used"] and dec.report["prompt"]["regions"] == ["foliage"], dec.report["prompt"]


@pytest.mark.parametrize("name,seed", CASES)
def test_made_things_stay_still(name: str, seed: int):
    d, dec = _staged(name, seed)
    report = _report(d, dec)
    still_share = float((dec.dynamic & d.still_mask()).sum() / max(dec.dynamic.sum(), 1))
    print(f"{d.name} seed {seed}: chosen {dec.report['chosen']}; {dec.result.ground.note or 'ground plane found'}; "
          f"moving per part {report}; share of the moving Gaussians labelled still {still_share:.4f}")
    wrong = {part: r for part, r in report.items() if r[0] and part not in TOLERATED}
    assert not wrong, (d.name, seed, wrong)
    if not d.effects:  # the yard: nothing moves at all
        assert not dec.report["chosen"] and not dec.dynamic.any(), (d.name, seed, dec.report["chosen"],
                                                                     int(dec.dynamic.sum()))
    assert still_share <= 0.03, (d.name, seed, still_share)


@pytest.mark.parametrize("seed", SEEDS)
def test_the_real_plant_in_the_hall_still_moves(seed: int):
    d, dec = _staged("hall", seed)
    leaves = d.gaussians.extras["label"].numpy() == LABEL_IDS["foliage"]
    recall = float(dec.dynamic[leaves].mean())
    print(f"hall seed {seed}: chosen {dec.report['chosen']}; the plant's leaves moving {recall:.3f} of {int(leaves.sum())}")
    assert set(d.effects) <= set(dec.report["chosen"]), (seed, dec.report["chosen"])
    assert recall >= 0.8, (seed, recall)
