"""What cannot move: each region's 3D candidates, checked against the model by a table of rules.

The photos' colour cues propose regions; the fitted model says what they lie on. Each region's lifted
Gaussians are split into 3D candidates (connected within ``link`` = ``link_frac`` x the neighbourhood
radius; flat and other parts apart), numbered for the overview and the user's corrections, and each
candidate goes through its region's row of :data:`TABLE` in order until a rule decides it (still, or
moved to another region). :data:`BEFORE` runs on the lifted regions before the candidates are formed,
:data:`AFTER` on the verdicts once every candidate is checked. Each rule is a unit: its knobs are the
fields of its class (config ``effects.rules.<name>``), its docstring says what it is for, what
motivated it and its test; ``config/README.md`` lists them (generated from this table).

Connected parts of fewer than ``min_candidate`` Gaussians (after the flat / other split, whose small
parts rejoin their component) are checked by the same rules but not numbered (under 3 Gaussians, where
no plane can be checked, they do not move); the Gaussians of those set aside are counted per region
(``fragments``).
"""
from __future__ import annotations

import dataclasses
import inspect
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from anigs.effects.kinds import REGIONS
from anigs.effects.outline import SmearedSheet
from anigs.effects.rules.base import Bands, Candidate, Context, Rule, Verdict
from anigs.effects.rules.blossoms import Blossoms
from anigs.effects.rules.held import Held
from anigs.effects.rules.islands import Islands, drop_islands
from anigs.effects.rules.made_surface import MadeSurface
from anigs.effects.rules.own_colour import OwnColour
from anigs.effects.rules.plane import Plane, fit_plane
from anigs.effects.rules.sunlit_leaves import SunlitLeaves
from anigs.typed_config import Section

#: per region, the rules each of its candidates goes through, in this order (the table is the order)
TABLE: dict[str, tuple[type, ...]] = {
    "foliage": (Plane, MadeSurface),
    "grass": (MadeSurface,),
    "flowers": (SunlitLeaves, OwnColour, Plane, MadeSurface, Held, Blossoms),
}
BEFORE: tuple[type, ...] = (Islands,)       # on the lifted regions, before the candidates are formed
AFTER: tuple[type, ...] = (SmearedSheet,)   # on the verdicts, once every candidate is checked
MIN_CHECKED = 3  # a part under this many Gaussians cannot be checked (no plane): it does not move

__all__ = ["AFTER", "BEFORE", "Bands", "Candidate", "Context", "Outcome", "RulesConfig", "TABLE", "Verdict",
           "check_candidates", "drop_islands", "fit_plane", "point_components", "rule_classes", "rules_markdown",
           "run_table", "split_flat"]


def rule_classes() -> list[type]:
    """Every rule class, in the order of the config: :data:`BEFORE`, the table's rules by first use, :data:`AFTER`."""
    out: list[type] = list(BEFORE)
    for row in TABLE.values():
        out += [r for r in row if r not in out]
    return out + [r for r in AFTER if r not in out]


@dataclass
class _Candidates:
    link_frac: float = 1.0           # a region's Gaussians within this x neighbour radius form one numbered candidate
    min_candidate: int = 10          # parts with fewer Gaussians are checked by the rules but not numbered


def _doc(cls: type) -> str:
    return (cls.__doc__ or "").strip().splitlines()[0]


#: config section ``effects.rules``: the candidates' link and size, and one nested section per rule (its knobs)
RulesConfig = dataclasses.make_dataclass(
    "RulesConfig", [(c.NAME, c, field(default_factory=c, metadata={"doc": _doc(c)})) for c in rule_classes()],
    bases=(_Candidates, Section), namespace={"WHERE": "effects.rules", "__doc__":
                                             "The geometry rules' knobs (config section ``effects.rules``)."})
RulesConfig.__module__ = __name__


def _paragraph(doc: str, label: str) -> str:
    """The paragraph of ``doc`` that starts with ``label`` (``Motivation:``, ``Test:``), on one line, without it."""
    for para in doc.split("\n\n"):
        if para.strip().startswith(label):
            return " ".join(para.strip()[len(label):].split())
    return ""


def rules_markdown() -> str:
    """The table of rules for ``config/README.md``: each rule's name, where it runs (region and place in its
    row), its knobs with their defaults, what motivated it and its test (from the rule module's docstring)."""
    lines = ["| rule | runs | knobs (`effects.rules.<rule>.`, default) | motivation | test |", "|---|---|---|---|---|"]
    for cls in rule_classes():
        where = [f"{region} {row.index(cls) + 1} of {len(row)}" for region, row in TABLE.items() if cls in row]
        if cls in BEFORE:
            where.append("plants, before the candidates")
        if cls in AFTER:
            where.append("after the table")
        doc = inspect.getmodule(cls).__doc__ or ""
        knobs = ", ".join(f"`{f.name}` {getattr(cls(), f.name)!r}" for f in dataclasses.fields(cls))
        what = _doc(cls).split(": ", 1)[-1]
        cells = [f"`{cls.NAME}`: {what}", "; ".join(where), knobs, _paragraph(doc, "Motivation:"),
                 _paragraph(doc, "Test:")]
        lines.append("| " + " | ".join(c.replace("|", "\\|").replace("``", "`") for c in cells) + " |")
    return "\n".join(lines) + "\n"


@dataclass
class Outcome:
    """What the rules decided: the new region per Gaussian ``region_of`` [N] (-1 none), the numbered
    ``candidates`` (kept or not, with the reason) and, per region, how many Gaussians of unnumbered small
    parts (or islands) they set aside (``fragments``)."""

    region_of: np.ndarray
    candidates: list[Candidate]
    fragments: dict[str, int]

    def __iter__(self):  # (region_of, candidates, fragments)
        return iter((self.region_of, self.candidates, self.fragments))


def point_components(points: np.ndarray, link: float) -> np.ndarray:
    """Connected components [M] (labels 0..) of ``points`` [M,3] linked within ``link``."""
    m = len(points)
    if m == 0:
        return np.zeros(0, np.int64)
    pairs = cKDTree(points).query_pairs(link, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    return connected_components(graph, directed=False)[1]


def split_flat(lab: np.ndarray, flat: np.ndarray, min_size: int) -> np.ndarray:
    """Component labels [M] split into their flat and other parts (``flat`` bool [M]); a part smaller
    than ``min_size`` stays with the rest of its component (the rim of a picture whose neighbourhood
    is not planar belongs to the picture), both when both are that small."""
    key = lab * 2 + flat.astype(np.int64)
    size = np.bincount(key, minlength=2 * (lab.max(initial=0) + 1))
    own, sib = size[key], size[key ^ 1]
    small = own < min_size
    key = np.where(small & (sib >= min_size), key ^ 1, key)
    key = np.where(small & (sib < min_size), lab * 2, key)
    return np.unique(key, return_inverse=True)[1]


def run_table(ctx: Context, rules: "RulesConfig", flat: np.ndarray | None = None,
              fragments: dict[str, int] | None = None) -> Outcome:
    """Split each region of ``ctx.region_of`` into candidates (flat and other parts apart, ``flat`` bool [N])
    and run its row of :data:`TABLE` on each (module docstring); numbered from 1 in ``REGIONS`` order,
    largest first."""
    out = ctx.region_of.copy()
    fragments = {} if fragments is None else fragments
    cands: list[Candidate] = []
    for k, name in enumerate(REGIONS):
        idx = np.flatnonzero(ctx.region_of == k)
        if not len(idx):
            continue
        row: Sequence[Rule] = [getattr(rules, r.NAME) for r in TABLE.get(name, ())]
        lab = point_components(ctx.means[idx], ctx.link)
        if flat is not None:  # flat parts apart from the rest
            lab = split_flat(lab, flat[idx], rules.min_candidate)
        sizes = np.bincount(lab)
        for c in np.argsort(-sizes, kind="stable"):
            sel = idx[lab == c]
            p = ctx.means[sel]
            cand = Candidate(0, name, sel, p.mean(0), float(np.linalg.norm(p.max(0) - p.min(0))))
            for rule in row:
                verdict = rule.check(cand, ctx)
                if verdict is not None:
                    cand.apply(verdict)
                    break
            if not cand.open:
                out[sel] = REGIONS.index(cand.moved_to) if cand.moved_to else -1
            if name in ctx.unasked and not cand.moved_to:
                continue  # a region the prompt did not ask for: what the rules did not move is still, not listed
            if sizes[c] >= rules.min_candidate:
                cands.append(cand)
            else:  # a small part (a lone blossom, a speck on a lawn) is checked, not numbered; under MIN_CHECKED
                if sizes[c] < MIN_CHECKED:  # Gaussians no plane can be checked: it does not move
                    cand.kept = False
                    out[sel] = -1
                if not cand.kept:
                    fragments[name] = fragments.get(name, 0) + len(sel)
        if name == ctx.blossoms_of:  # blossoms attach only to the plants every rule kept
            ctx.bear(out)
    for i, cand in enumerate(cands):
        cand.number = i + 1
    return Outcome(out, cands, fragments)


def check_candidates(means: np.ndarray, colours: np.ndarray, region_of: np.ndarray, height: np.ndarray | None,
                     cam_height: float, radius: float, cfg, flat: np.ndarray | None = None,
                     seed: int = 0, above_cameras: np.ndarray | None = None, blossoms_of: str | None = None,
                     flattest: np.ndarray | None = None) -> Outcome:
    """The rules on the lifted regions: :data:`BEFORE`, then :func:`run_table` (module docstring).

    Args:
        means: Gaussian centres [N,3]; colours: their own RGB [N,3] in [0,1].
        region_of: region id [N] (index into ``REGIONS``, -1 none).
        height: height above the ground plane [N] (None: no plane); cam_height: the cameras' height.
        radius: the neighbourhood radius of the local shape (world units).
        cfg: the effects :class:`~anigs.effects.config.EffectsConfig` (its ``rules`` and the colour bands of ``regions``).
        flat: bool [N], Gaussians whose neighbourhood is planar: flat and other Gaussians form separate
            candidates (a lawn bank under a tree, a facade behind it are not the crown).
        above_cameras: bool [N], Gaussians higher (along up) than every camera (None: not checked).
        blossoms_of: the region whose plants' blossoms the flowers are (rule ``blossoms``; None: flowers are
            their own region, and then the flowers are ``unasked``).
        flattest: [N,3] each Gaussian's unit flattest axis (rule ``made_surface``; None: that rule passes).
    Returns an :class:`Outcome` (it unpacks as ``region_of, candidates, fragments``).
    """
    rules = cfg.rules
    fragments: dict[str, int] = {}
    if rules.islands.on:
        region_of = rules.islands.apply(means, region_of, fragments)
    ctx = Context(means, colours, region_of, height, cam_height, radius, rules.link_frac * radius,
                  cfg.regions.bands(), above_cameras, blossoms_of,
                  tuple(r for r, row in TABLE.items() if Blossoms in row) if blossoms_of else (), seed, flattest)
    return run_table(ctx, rules, flat, fragments)
