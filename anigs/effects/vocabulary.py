"""The prompt, understood as people write it: which words name which kinds of motion (regions).

``prompt_kinds(prompt) -> PromptKinds``: the regions (foliage, grass, flowers, water) a prompt
names, with the words that matched and the words not understood. A word is looked up by its
dictionary forms (:mod:`anigs.effects.lexicon` lists only those):

1. the word itself, then its lemmas from ``lemminflect`` (an English lemmatizer whose dictionary
   ships in its wheel: no download), as a noun or adjective ("leaves" -> leaf, "lilies" -> lily)
   and, for the few growth verbs of ``lexicon.VERBS``, as a verb ("flowering" -> flower,
   "overgrown" -> overgrow); other verbs are not looked up ("waving" trees are not water);
2. a derived adjective by its suffix: "leafy" -> leaf, "grassy" -> grass, "flowery" -> flower,
   "wooded" -> wood;
3. a compound by its parts, the last one heading it: "wildflowers" -> flower, "rosebush" -> rose
   and bush; when the head names nothing ("flowerpot", "treehouse") the compound names nothing;
4. two-word terms ("water lily", "flower bed") before their parts.

A word after a negation ("no", "not", "without") names nothing ("a room without plants"). Words
that are neither in the lexicon, nor in the lemmatizer's English dictionary, nor a function word
are *not understood* (a typo, a rare name): ``unknown``, listed in effects.json and on the
overview so the user sees why a scene stays still.

With ``effects: auto`` the effects stage localises only the regions the prompt names; a prompt
that names none gives a still scene. config/README.md lists the lexicon (generated from here).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import lru_cache

from anigs.effects.config import REGION_EFFECTS, REGIONS
from anigs.effects.lexicon import FUNCTION_WORDS, GENERIC, PLANTS, SCENES, STILL, VERBS, table

NEGATIONS = ("no", "not", "without", "nor", "never")
_TOKEN = re.compile(r"[a-z]+(?:'[a-z]+)?|[,.;:!?]")
TERMS = table()
#: derived adjectives: suffix -> what replaces it ("leafy" -> "leaf", "wooded" -> "wood", "flowery" -> "flower")
_DERIVED = (("iest", "y"), ("ier", "y"), ("y", ""), ("ed", ""), ("s", ""))
_MIN_PART = 3  # the shortest part of a compound


@dataclass
class PromptKinds:
    """What a prompt names: ``regions`` in ``REGIONS`` order, ``matches`` word -> regions it named,
    ``negated`` the words a negation switched off, ``unknown`` the words not understood."""

    prompt: str
    regions: list[str] = field(default_factory=list)
    matches: dict[str, list[str]] = field(default_factory=dict)
    negated: list[str] = field(default_factory=list)
    unknown: list[str] = field(default_factory=list)

    @property
    def effects(self) -> list[str]:
        """The effects of the named regions (``foliage`` -> foliage_sway, leaf_flutter ...)."""
        return [e for r in self.regions for e in REGION_EFFECTS[r]]

    def to_json(self) -> dict:
        return {"prompt": self.prompt, "regions": list(self.regions), "words": dict(self.matches),
                "negated": list(self.negated), "unknown": list(self.unknown)}


def _lemmas(word: str) -> list[str]:
    """The word's dictionary forms: nouns and adjectives, and verbs of ``VERBS`` (see module docstring)."""
    from lemminflect import getAllLemmas

    out = []
    for pos, lemmas in getAllLemmas(word).items():
        for lem in lemmas:
            if pos in ("NOUN", "ADJ", "PROPN") or (pos == "VERB" and lem in VERBS):
                out.append(lem)
    return out


def _known_english(word: str) -> bool:
    from lemminflect import getAllLemmas

    return bool(getAllLemmas(word))


@lru_cache(maxsize=4096)
def lookup(word: str) -> tuple[tuple[str, ...], bool]:
    """(regions ``word`` names, whether it is understood) for one lower-case word."""
    forms = [word, *_lemmas(word)]
    for f in forms:
        if f in TERMS:
            return TERMS[f], True
    for f in forms if _adjective_or_unknown(word) else ():  # a derived adjective, a plural the dictionary lacks
        for suffix, repl in _DERIVED:
            if f.endswith(suffix) and len(f) - len(suffix) >= _MIN_PART:
                base = f[: len(f) - len(suffix)] + repl
                for b in (base, base[:-1] if len(base) > _MIN_PART and base[-1] == base[-2] else None):
                    if b and b in TERMS:
                        return TERMS[b], True
    known = _known_english(word) or word in FUNCTION_WORDS or word in STILL
    for f in dict.fromkeys([word, *_lemmas(word), *_oov_lemmas(word)]):  # a compound: "wildflowers", "rosebush"
        split = _compound(f)
        if split is not None:
            return split, True
    return (), known


def _adjective_or_unknown(word: str) -> bool:
    """Not only a verb form ("parked" is no park, "leafy" and "wooded" are adjectives)."""
    from lemminflect import getAllLemmas

    lem = getAllLemmas(word)
    return not lem or "ADJ" in lem or "NOUN" in lem


def _oov_lemmas(word: str) -> list[str]:
    from lemminflect import getAllLemmasOOV

    return [lem for lemmas in getAllLemmasOOV(word, "NOUN").values() for lem in lemmas]


def _compound(word: str) -> tuple[str, ...] | None:
    """The regions of a compound ``word`` (modifier + head), None when it is not one of known parts."""
    for i in range(_MIN_PART, len(word) - _MIN_PART + 1):
        left, right = word[:i], word[i:]
        head = TERMS.get(right) if right not in SCENES else None
        if head is None:
            head_known = _known_english(right)
            if not head_known:
                continue
            if left in TERMS or _known_english(left):
                return ()  # a flowerpot, a treehouse: the head names nothing that moves
            continue
        if not head:
            return ()
        if left in TERMS or _known_english(left):
            return tuple(r for r in REGIONS if r in head or r in TERMS.get(left, ()))
    return None


def prompt_kinds(prompt: str | None) -> PromptKinds:
    """The regions ``prompt`` names (see module docstring); an empty prompt names none."""
    text = str(prompt or "")
    tokens = [t.replace("'s", "").replace("'", "") for t in _TOKEN.findall(text.lower())]
    found: dict[str, list[str]] = {}
    negated: list[str] = []
    unknown: list[str] = []
    neg_left = 0  # a negation covers the next few words up to a punctuation mark ("no trees or flowers")
    i = 0
    while i < len(tokens):
        tok = tokens[i]
        if tok in NEGATIONS:
            neg_left, i = 4, i + 1
            continue
        if not tok or not tok[0].isalpha():  # , . ; ! ? end a negation's reach
            neg_left, i = 0, i + 1
            continue
        regions, step, term = (), 1, tok
        if i + 1 < len(tokens) and tokens[i + 1][:1].isalpha():
            nxt = tokens[i + 1]
            for second in dict.fromkeys([nxt, *_lemmas(nxt)]):
                pair = f"{tok} {second}"
                if pair in TERMS:
                    regions, step, term = TERMS[pair], 2, f"{tok} {nxt}"
                    break
        if step == 1:
            regions, understood = lookup(tok)
            if not understood and tok not in FUNCTION_WORDS and tok not in unknown:
                unknown.append(tok)
        if regions:
            (negated.append(term) if neg_left > 0 else found.setdefault(term, [r for r in REGIONS if r in regions]))
        neg_left, i = max(neg_left - step, 0), i + step
    regions = [r for r in REGIONS if any(r in v for v in found.values())]
    return PromptKinds(text, regions, found, negated, unknown)


def vocabulary_markdown() -> str:
    """The lexicon as a Markdown table (config/README.md)."""
    rows = ["| kinds (effects) | words (dictionary forms; plurals, inflections, derived adjectives and compounds "
            "of them count too) |", "|---|---|"]
    groups: dict[tuple[str, ...], list[str]] = {}
    for w, regions in {**GENERIC, **PLANTS}.items():
        if regions:
            groups.setdefault(regions, []).append(w)
    for regions, words in groups.items():
        effects = ", ".join(e for r in regions for e in REGION_EFFECTS[r])
        rows.append(f"| {', '.join(regions)} ({effects}) | {', '.join(words)} |")
    return "\n".join(rows)
