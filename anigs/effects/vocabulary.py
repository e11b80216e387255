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

Words that name nothing that moves here, listed in effects.json and on the overview:

5. a word after a negation ("no", "not", "without") is *negated* ("a room without plants");
6. what the prompt says stays still is negated too: the words of the lexicon before a negated motion
   verb ("the flowers must not move") or a stillness after a verb of staying ("the grass stays still",
   "is motionless"), back to the start of their clause (a mark, "but", "while", or a motion verb:
   "the trees sway and the flowers stay still" keeps the trees);
   and a whole scene said to stay still ("nothing moves", "no wind") negates every word;
7. a depiction or a made thing is *depicted*: the words after a picture's noun and "of" ("a painting
   of trees", "a still life of tulips", "the reflection of trees"), a word just before such a noun
   ("rose wallpaper", "a tree sculpture"), and the words right after an adjective of made things
   ("plastic plants", "fake flowers"; its reach ends at another noun: "a stone wall with ivy").

A scene word's kinds ("a garden") lose those of its negated words ("a garden with no flowers"); a
plant named outright keeps its own ("a rose garden without trees": the rose's leaves). Words
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
from anigs.effects.lexicon import (ARTIFICIAL, CLAUSE, DEPICTIONS, FUNCTION_WORDS, GENERIC, MOTION, MOVERS, PLANTS,
                                   SCENES, STAY, STILL, STILLNESS, VERBS, table)

NEGATIONS = ("no", "not", "without", "nor", "never")
_TOKEN = re.compile(r"[^\W\d_]+(?:'[^\W\d_]+)?|[,.;:!?]")  # words of letters (any script), marks
TERMS = table()
#: derived adjectives: suffix -> what replaces it ("leafy" -> "leaf", "wooded" -> "wood", "flowery" -> "flower")
_DERIVED = (("iest", "y"), ("ier", "y"), ("y", ""), ("ed", ""), ("s", ""))
_MIN_PART = 3  # the shortest part of a compound
LOOKUP_CACHE = 4096  # the words whose lookup is remembered (count)
#: a stillness word's reach back: "not" before a motion verb ("do not move"), a verb of staying before a stillness
#: word ("stay still") counts within this many words before it (words)
STILL_REACH = 3
ALL_STILL_REACH = 3  # "nothing" or "none" reaches a motion verb within this many words after it (words) ...
MOVER_REACH = 2  # ... a negation a mover ("no wind", "without any breeze") within this many (words)
NEGATION_REACH = 4  # a negation ("no trees or flowers") covers this many words after it (words)
MADE_REACH = 3  # a made-thing adjective ("plastic trees") covers this many words after it (words)
#: the words a depiction's list ("a painting of trees and a lake") goes on through
_DEPICTED_LIST = frozenset(("a", "an", "the", "and", "or", "of", "with", "some", "many", "few", "two", "three", "its",
                            "their"))


@dataclass
class PromptKinds:
    """What a prompt names: ``regions`` in ``REGIONS`` order, ``matches`` word -> regions it named,
    ``negated`` the words a negation or a stillness switched off, ``unknown`` the words not understood,
    ``depicted`` the words of depictions and made things."""

    prompt: str
    regions: list[str] = field(default_factory=list)
    matches: dict[str, list[str]] = field(default_factory=dict)
    negated: list[str] = field(default_factory=list)
    unknown: list[str] = field(default_factory=list)
    depicted: list[str] = field(default_factory=list)

    @property
    def effects(self) -> list[str]:
        """The effects of the named regions (``foliage`` -> foliage_sway, leaf_flutter ...)."""
        return [e for r in self.regions for e in REGION_EFFECTS[r]]

    def to_json(self) -> dict:
        return {"prompt": self.prompt, "regions": list(self.regions), "words": dict(self.matches),
                "negated": list(self.negated), "depicted": list(self.depicted), "unknown": list(self.unknown)}


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


@lru_cache(maxsize=LOOKUP_CACHE)
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


def _lemma_in(word: str, words: frozenset, pos: str | None = None) -> bool:
    """Whether ``word`` or one of its lemmas (of part of speech ``pos``, any when None) is in ``words``."""
    from lemminflect import getAllLemmas

    if word in words:
        return True
    return any(lem in words for p, lems in getAllLemmas(word).items() if pos is None or p == pos for lem in lems)


def _is_noun(word: str) -> bool:
    """A word the dictionary knows as a noun ("wall", "fence"; not "potted", "leafy") or a function word."""
    from lemminflect import getAllLemmas

    return word in FUNCTION_WORDS or "NOUN" in getAllLemmas(word)


def _tokens(text: str) -> list[str]:
    """Lower-case words and punctuation marks; "n't" is "not", "'s" is dropped."""
    text = text.lower().replace("\u2019", "'").replace("n't", " not")
    return [t.replace("'s", "").replace("'", "") for t in _TOKEN.findall(text)]


def _stillness_at(tokens: list[str], i: int) -> bool:
    """Whether ``tokens[i]`` says that what comes before it stays still: a negated motion verb ("do
    not move") or a stillness word after a verb of being or staying ("stay still", "is motionless")."""
    tok = tokens[i]
    if _lemma_in(tok, MOTION, "VERB") and "not" in tokens[max(i - STILL_REACH, 0):i] and "only" not in tokens[i - 1:i]:
        return True
    if tok in STILLNESS:
        before = tokens[max(i - STILL_REACH, 0):i]
        after = tokens[i + 1] if i + 1 < len(tokens) else ""
        return any(_lemma_in(b, STAY, "VERB") for b in before) and not _lemma_in(after, MOTION, "VERB")
    return False


def _all_still_at(tokens: list[str], i: int) -> bool:
    """Whether ``tokens[i]`` starts a stillness of the whole scene: "nothing" or "none" before a motion
    verb ("nothing moves", "nothing is moving"), a negation before a mover ("no wind", "without any breeze")."""
    tok, after = tokens[i], tokens[i + 1:i + 1 + ALL_STILL_REACH]
    if tok in ("nothing", "none"):
        return any(_lemma_in(t, MOTION, "VERB") for t in after)
    if tok == "windless":
        return True
    return tok in NEGATIONS and any(_lemma_in(t, MOVERS, "NOUN") for t in after[:MOVER_REACH])


def _term_at(tokens: list[str], i: int) -> tuple[tuple[str, ...], int, str, bool]:
    """(regions, tokens used, the term as written, understood) of the word or two-word term at ``i``."""
    tok = tokens[i]
    if i + 1 < len(tokens) and tokens[i + 1][:1].isalpha():
        nxt = tokens[i + 1]
        for second in dict.fromkeys([nxt, *_lemmas(nxt)]):
            if f"{tok} {second}" in TERMS:
                return TERMS[f"{tok} {second}"], 2, f"{tok} {nxt}", True
    regions, understood = lookup(tok)
    return regions, 1, tok, understood or tok in FUNCTION_WORDS or _lemma_in(tok, DEPICTIONS, "NOUN") \
        or tok in ARTIFICIAL or tok in STILLNESS


def prompt_kinds(prompt: str | None) -> PromptKinds:
    """The regions ``prompt`` names (see module docstring); an empty prompt names none."""
    text = str(prompt or "")
    tokens = _tokens(text)
    hits: list[list] = []  # [term, regions, state: named | negated | depicted] in prompt order
    unknown: list[str] = []
    neg_left = art_left = 0  # how far a negation ("no trees or flowers") and a made-thing adjective reach
    depicting = False  # inside "a painting of ..." up to the next mark or clause word
    clause = 0  # the first hit of the current clause (what a stillness switches off)
    everything_still = False
    i = 0
    while i < len(tokens):
        tok = tokens[i]
        if not tok[:1].isalpha() or tok in CLAUSE:  # a mark or a clause word ends every reach
            neg_left = art_left = 0
            depicting, clause, i = False, len(hits), i + 1
            continue
        if _stillness_at(tokens, i):  # "... stay still", "... do not move": off with the clause's words
            for h in hits[clause:]:
                h[2] = "negated" if h[2] == "named" else h[2]
            i += 1
            continue
        if _lemma_in(tok, MOTION, "VERB") and not lookup(tok)[0]:  # "the trees sway and ...": a new reach
            clause, i = len(hits), i + 1
            continue
        if _all_still_at(tokens, i):  # "nothing moves", "no wind": the whole scene stays still
            everything_still = True
        if tok in NEGATIONS and tokens[i + 1:i + 2] != ["only"]:
            neg_left, i = NEGATION_REACH, i + 1
            continue
        if tok in ARTIFICIAL:
            art_left, i = MADE_REACH, i + 1
            continue
        if _lemma_in(tok, DEPICTIONS, "NOUN") or (tok == "still" and tokens[i + 1:i + 2] == ["life"]):
            step = 2 if tok == "still" else 1
            depicting = depicting or tokens[i + step:i + step + 1] == ["of"]
            if hits and hits[-1][3] == i - 1 and hits[-1][2] == "named" and not _is_scene(hits[-1][0]):
                hits[-1][2] = "depicted"  # "rose wallpaper", "a leaf print"
            i += step
            continue
        if depicting and tok in FUNCTION_WORDS and tok not in _DEPICTED_LIST:
            depicting = False  # "the reflection of trees in the lake": the lake is real
        regions, step, term, understood = _term_at(tokens, i)
        if not understood and tok not in unknown:
            unknown.append(tok)
        if regions:
            state = "negated" if neg_left > 0 else "depicted" if (depicting or art_left > 0) else "named"
            hits.append([term, [r for r in REGIONS if r in regions], state, i + step - 1])
            art_left = 0
        elif art_left and _is_noun(tok):
            art_left = 0  # "a stone wall with ivy": the adjective was the wall's
        neg_left, art_left, i = max(neg_left - step, 0), max(art_left - step, 0), i + step
    if everything_still:
        for h in hits:
            h[2] = "negated" if h[2] == "named" else h[2]
    return _kinds(text, hits, unknown)


def _is_scene(term: str) -> bool:
    return any(f in SCENES for f in (term, *_lemmas(term)))


def _kinds(text: str, hits: list[list], unknown: list[str]) -> PromptKinds:
    """The prompt's kinds from its hits: the named words' regions, less those of switched-off words
    where only a scene word ("a garden with no flowers") named them."""
    found: dict[str, list[str]] = {}
    for term, regions, state, _ in hits:
        if state == "named":
            found.setdefault(term, regions)
    off = {r for _, regions, state, _ in hits if state == "negated" for r in regions}
    named = {r for t, regions in found.items() if not _is_scene(t) for r in regions}
    regions = [r for r in REGIONS if any(r in v for v in found.values()) and (r in named or r not in off)]
    return PromptKinds(text, regions, found, [h[0] for h in hits if h[2] == "negated"],
                       unknown, [h[0] for h in hits if h[2] == "depicted"])


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
    rows += ["", "Words that switch the lexicon's words off (they then name nothing that moves, and effects.json "
             "and the overview list them): a negation (" + ", ".join(NEGATIONS) + "); a negated motion verb ("
             + ", ".join(sorted(MOTION)) + ") or a stillness (" + ", ".join(sorted(STILLNESS)) + ") after a verb of "
             "staying, for the words before it in its clause; a depiction (" + ", ".join(sorted(DEPICTIONS))
             + ") for the words after its \"of\" and the word just before it; an adjective of made things ("
             + ", ".join(sorted(ARTIFICIAL)) + ") for the words right after it; \"nothing\" or \"none\" before a "
             "motion verb, or a negation before a mover (" + ", ".join(sorted(MOVERS)) + "), for every word."]
    return "\n".join(rows)
