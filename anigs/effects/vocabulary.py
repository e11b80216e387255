"""The prompt's vocabulary: which words name which kinds of motion (regions), in one place.

``prompt_kinds(prompt) -> PromptKinds``: the regions (foliage, grass, flowers, water) a prompt
names, directly (``WORDS``: "trees" -> foliage) or through a scene word that implies several
(``SCENE_WORDS``: "garden" -> foliage, grass, flowers), with the words that matched. Matching is
on whole lower-case words, singular or plural ("leaf"/"leaves", "bush"/"bushes"), and two-word
terms ("weeping willow") before their parts. A word after a negation ("no", "without", "not")
names nothing ("a room without plants").

With ``effects: auto`` the effects stage localises only the regions the prompt names; a prompt
that names none gives a still scene. config/README.md lists this table (generated from here).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from anigs.effects.config import REGION_EFFECTS, REGIONS

WORDS: dict[str, tuple[str, ...]] = {
    "foliage": ("tree", "trees", "leaf", "leaves", "foliage", "bush", "bushes", "shrub", "shrubs", "hedge", "hedges",
                "plant", "plants", "frond", "fronds", "fern", "ferns", "branch", "branches", "twig", "twigs",
                "palm", "palms", "ivy", "vine", "vines", "canopy", "willow", "willows",
                "houseplant", "houseplants", "greenery", "vegetation", "weeping willow"),
    "grass": ("grass", "grasses", "lawn", "lawns", "meadow", "meadows", "reed", "reeds", "turf", "wheat", "field",
              "fields", "prairie"),
    "flowers": ("flower", "flowers", "blossom", "blossoms", "rose", "roses", "bloom", "blooms", "tulip", "tulips",
                "daisy", "daisies", "petal", "petals", "sunflower", "sunflowers", "lily", "lilies", "orchid",
                "orchids", "flowerbed", "flowerbeds", "flower bed", "flower beds"),
    "water": ("water", "pond", "ponds", "lake", "lakes", "river", "rivers", "fountain", "fountains", "sea", "ocean",
              "stream", "streams", "creek", "pool", "pools", "waves", "ripples", "waterfall"),
}
SCENE_WORDS: dict[str, tuple[str, ...]] = {
    "garden": ("foliage", "grass", "flowers"), "gardens": ("foliage", "grass", "flowers"),
    "park": ("foliage", "grass", "flowers"), "parks": ("foliage", "grass", "flowers"),
    "backyard": ("foliage", "grass", "flowers"), "yard": ("foliage", "grass", "flowers"),
    "forest": ("foliage",), "woods": ("foliage",), "orchard": ("foliage",), "jungle": ("foliage",),
    "greenhouse": ("foliage", "flowers"), "pasture": ("grass",),
}
NEGATIONS = ("no", "not", "without", "nor", "never")
_TOKEN = re.compile(r"[a-z]+|[,.;:!?]")


@dataclass
class PromptKinds:
    """What a prompt names: ``regions`` in ``REGIONS`` order, ``matches`` word -> regions it named,
    ``negated`` the region words a negation switched off."""

    prompt: str
    regions: list[str] = field(default_factory=list)
    matches: dict[str, list[str]] = field(default_factory=dict)
    negated: list[str] = field(default_factory=list)

    @property
    def effects(self) -> list[str]:
        """The effects of the named regions (``foliage`` -> foliage_sway, leaf_flutter ...)."""
        return [e for r in self.regions for e in REGION_EFFECTS[r]]

    def to_json(self) -> dict:
        return {"prompt": self.prompt, "regions": list(self.regions), "words": dict(self.matches),
                "negated": list(self.negated)}


def _table() -> dict[str, tuple[str, ...]]:
    """Every term (one or two words) -> the regions it names."""
    out: dict[str, tuple[str, ...]] = {}
    for region, words in WORDS.items():
        for w in words:
            out[w] = tuple(sorted(set(out.get(w, ())) | {region}, key=REGIONS.index))
    for w, regions in SCENE_WORDS.items():
        out[w] = tuple(sorted(set(out.get(w, ())) | set(regions), key=REGIONS.index))
    return out


TERMS = _table()


def prompt_kinds(prompt: str | None) -> PromptKinds:
    """The regions ``prompt`` names (see module docstring); an empty prompt names none."""
    text = str(prompt or "")
    tokens = _TOKEN.findall(text.lower())
    found: dict[str, list[str]] = {}
    negated: list[str] = []
    neg_left = 0  # a negation covers the next few words up to a punctuation mark ("no trees or flowers")
    i = 0
    while i < len(tokens):
        tok = tokens[i]
        if tok in NEGATIONS:
            neg_left, i = 4, i + 1
            continue
        if not tok[0].isalpha():  # , . ; ! ? end a negation's reach
            neg_left, i = 0, i + 1
            continue
        pair = f"{tok} {tokens[i + 1]}" if i + 1 < len(tokens) else ""
        term = pair if pair in TERMS else tok if tok in TERMS else None
        if term is not None:
            (negated.append(term) if neg_left > 0 else found.setdefault(term, list(TERMS[term])))
        step = 2 if term is not None and term == pair else 1
        neg_left, i = max(neg_left - step, 0), i + step
    regions = [r for r in REGIONS if any(r in v for v in found.values())]
    return PromptKinds(text, regions, found, negated)


def vocabulary_markdown() -> str:
    """The vocabulary as a Markdown table (config/README.md)."""
    rows = ["| kind (effects) | words in the prompt |", "|---|---|"]
    for r in REGIONS:
        rows.append(f"| {r} ({', '.join(REGION_EFFECTS[r])}) | {', '.join(WORDS[r])} |")
    scene = {}
    for w, regions in SCENE_WORDS.items():
        scene.setdefault(regions, []).append(w)
    for regions, words in scene.items():
        rows.append(f"| {', '.join(regions)} (scene words) | {', '.join(words)} |")
    return "\n".join(rows)
