"""``anigs study tally``: 2AFC answer files -> Table 4 (preference for ours per comparison and question).

Answers are read from exported JSON files (``anigs-study-export/1``, a list of answers, or one
answer) and from the server's JSONL files, then excluded, in this order, with the reason kept:

1. ``malformed``: not JSON, or not a valid answer (:mod:`anigs.study.schema`);
2. ``other_study``: another study id, or a pair/fields not in the given manifest;
3. ``duplicate``: a second answer to the same (participant, pair, question); the earliest counts;
4. ``incomplete``: every answer of a participant who did not answer all pairs and questions;
5. ``failed_catch``: every answer of a participant who preferred the blurred copy in more than
   ``max_catch_errors`` attention checks (:mod:`anigs.study.catch`);
6. ``careless``: every answer of a participant with more than ``max_fast_fraction`` too-fast answers;
7. ``too_fast``: an answer given less than ``min_time_ms`` after the pair was shown.

Answers to attention checks never enter the table; ``Tally.catch`` keeps them.

The rate is the fraction of answers preferring ours, with a binomial interval (Wilson score by
default, Clopper-Pearson on request) that treats answers as independent; the long CSV adds the
exact two-sided binomial test against 50%, the participant counts and a participant (cluster)
bootstrap interval, which does not assume that one participant's answers are independent.
"""
from __future__ import annotations

import csv
import io
import json
from collections import Counter, defaultdict
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterable, Sequence

from anigs.io import atomic_write_text, read_json, write_json
from anigs.study.build import default_label
from anigs.study.catch import catch_failed, is_catch
from anigs.study.schema import EXPORT_SCHEMA, QUESTIONS, answer_key, answer_problems, prefers_ours
from anigs.study.stats import binomial_p, cluster_bootstrap, interval
from anigs.reports.tables import Cell, Table, to_csv, to_latex, to_markdown

REASONS = ("malformed", "other_study", "duplicate", "incomplete", "failed_catch", "careless", "too_fast")
REASON_LABELS = {"malformed": "malformed", "other_study": "not in this study", "duplicate": "duplicate",
                 "incomplete": "incomplete participant",
                 "failed_catch": "failed attention checks", "careless": "careless participant (mostly too fast)",
                 "too_fast": "too fast"}


@dataclass
class TallyOptions:
    """Exclusion rules and the interval."""

    min_time_ms: float = 1000.0  # answers faster than this (from the pair being shown) are excluded
    max_fast_fraction: float = 0.5  # a participant with a larger share of too-fast answers is excluded
    require_complete: bool = True  # drop participants who did not answer every pair and question
    max_catch_errors: int = 0  # attention checks a participant may fail
    ci: str = "wilson"  # or "clopper-pearson"
    level: float = 0.95


@dataclass
class Exclusion:
    source: str
    reason: str  # one of REASONS
    detail: str
    participant: str = ""
    pair: str = ""
    question: str = ""


@dataclass
class Tally:
    """Answers kept, exclusions, and the resulting rows."""

    answers: list[dict[str, Any]]
    exclusions: list[Exclusion]
    participants_seen: list[str]
    catch: list[dict[str, Any]] = field(default_factory=list)  # attention-check answers of kept participants
    rows: list[dict[str, Any]] = field(default_factory=list)
    records: list[tuple[str, Any]] = field(default_factory=list)  # everything read, for the participants file


def read_answer_files(paths: Iterable[str | Path]) -> tuple[list[tuple[str, Any]], list[Exclusion]]:
    """(source, record) of every answer in the files; unparsable JSONL lines become exclusions."""
    out: list[tuple[str, Any]] = []
    bad: list[Exclusion] = []
    for p in map(Path, paths):
        if p.suffix == ".jsonl":
            for i, line in enumerate(p.read_text().splitlines(), 1):
                if line.strip():
                    try:
                        out.append((f"{p.name}:{i}", json.loads(line)))
                    except ValueError as exc:
                        bad.append(Exclusion(f"{p.name}:{i}", "malformed", f"not JSON: {exc}"))
            continue
        data = read_json(p)
        if isinstance(data, dict) and data.get("schema") == EXPORT_SCHEMA:
            data = data.get("answers")
            if not isinstance(data, list):
                raise ValueError(f"{p}: an export file needs an 'answers' list")
        items = data if isinstance(data, list) else [data]
        out += [(f"{p.name}#{i}", a) for i, a in enumerate(items)]
    return out, bad


def _exclude(a: dict[str, Any], source: str, reason: str, detail: str) -> Exclusion:
    return Exclusion(source, reason, detail, a.get("participant", ""), a.get("pair", ""), a.get("question", ""))


def select_answers(records: Sequence[tuple[str, Any]], manifest: dict[str, Any] | None = None,
                   opts: TallyOptions | None = None, pre_excluded: Sequence[Exclusion] = ()) -> Tally:
    """Apply the exclusion rules of the module doc; return the kept answers and the exclusions."""
    opts = opts or TallyOptions()
    excl = list(pre_excluded)
    valid: list[tuple[str, dict[str, Any]]] = []
    for src, a in records:
        problems = answer_problems(a)
        if problems:
            excl.append(_exclude(a if isinstance(a, dict) else {}, src, "malformed", "; ".join(problems)))
        else:
            valid.append((src, a))
    pairs = {t["id"]: t for t in manifest["trials"]} if manifest else None
    if manifest is None:
        ids = sorted({a["study_id"] for _, a in valid})
        if len(ids) > 1:
            raise ValueError(f"answers of several studies {ids}: give the study's manifest to pick one")
    kept: list[tuple[str, dict[str, Any]]] = []
    for src, a in valid:
        if manifest is not None and a["study_id"] != manifest["study_id"]:
            excl.append(_exclude(a, src, "other_study", f"study_id {a['study_id']} is not {manifest['study_id']}"))
        elif pairs is not None and (a["pair"] not in pairs or any(
                a[k] != pairs[a["pair"]][k] for k in ("scene", "view", "ours", "other"))):
            excl.append(_exclude(a, src, "other_study", f"pair {a['pair']} does not match the manifest"))
        else:
            kept.append((src, a))
    participants_seen = list(dict.fromkeys(a["participant"] for _, a in valid))
    # duplicates: the earliest answer (by time, then file order) to a (participant, pair, question) counts
    first: dict[tuple, tuple[str, dict[str, Any]]] = {}
    for src, a in sorted(kept, key=lambda sa: sa[1]["answered_at"]):
        k = answer_key(a)
        if k in first:
            same = {**a, "received_at": None} == {**first[k][1], "received_at": None}
            excl.append(_exclude(a, src, "duplicate", ("same answer as " if same else "answered again after ")
                                 + first[k][0]))
        else:
            first[k] = (src, a)
    unique = sorted(first.values(), key=lambda sa: (sa[1]["participant"], sa[1]["trial"], sa[1]["question"]))
    n_questions = len(manifest["questions"]) if manifest else len(QUESTIONS)
    by_pid: dict[str, list[tuple[str, dict[str, Any]]]] = defaultdict(list)
    for src, a in unique:
        by_pid[a["participant"]].append((src, a))
    answers: list[dict[str, Any]] = []
    catch: list[dict[str, Any]] = []
    for items in by_pid.values():
        expected = (len(pairs) if pairs else items[0][1]["n_trials"]) * n_questions
        failed = sum(catch_failed(a) for _, a in items)
        checks = [a for _, a in items if is_catch(a)]
        scored = [(s, a) for s, a in items if not is_catch(a)]
        fast = [a["time_ms"] < opts.min_time_ms for _, a in scored]
        if opts.require_complete and len(items) < expected:
            excl += [_exclude(a, s, "incomplete", f"participant answered {len(items)} of {expected}") for s, a in items]
        elif failed > opts.max_catch_errors:
            excl += [_exclude(a, s, "failed_catch", f"preferred the blurred copy in {failed} attention checks")
                     for s, a in items]
        elif sum(fast) > opts.max_fast_fraction * len(scored):
            excl += [_exclude(a, s, "careless", f"{sum(fast)} of {len(scored)} answers faster than "
                                                 f"{opts.min_time_ms:g} ms") for s, a in items]
        else:
            catch += checks
            for (s, a), f in zip(scored, fast):
                if f:
                    excl.append(_exclude(a, s, "too_fast", f"{a['time_ms']:g} ms < {opts.min_time_ms:g} ms"))
                else:
                    answers.append(a)
    return Tally(answers, excl, participants_seen, catch)


def side_bias(answers: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """How often the left video was chosen (0.5: no side bias), with a Wilson interval."""
    k, n = sum(a["side"] == "left" for a in answers), len(answers)
    return {"left": k, "answers": n, "rate": k / n if n else None,
            "ci": list(interval(k, n, "wilson")) if n else None}


def _num(v: Any) -> float:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else float("nan")


def participants_csv(records: Sequence[tuple[str, Any]], t: Tally) -> str:
    """One row per participant: answers given, used, excluded (by reason), median time, left rate."""
    import statistics

    given: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for _, a in records:
        if isinstance(a, dict) and isinstance(a.get("participant"), str):  # malformed ones too
            given[a["participant"]].append(a)
    used = Counter(a["participant"] for a in t.answers)
    excl: dict[str, Counter] = defaultdict(Counter)
    for e in t.exclusions:
        excl[e.participant][e.reason] += 1
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["participant", "answers", "used", "excluded", "median_time_ms", "left_rate"])
    for pid, items in given.items():
        w.writerow([pid, len(items), used[pid], " ".join(f"{r}:{c}" for r, c in sorted(excl[pid].items())),
                    f"{statistics.median(_num(a.get('time_ms')) for a in items):.0f}",
                    f"{sum(a.get('side') == 'left' for a in items) / len(items):.3f}"])
    return buf.getvalue()


def tally_rows(t: Tally, manifest: dict[str, Any] | None, opts: TallyOptions) -> list[dict[str, Any]]:
    """One row per (question, comparison, scene or 'All'): counts, rate, interval, exact p."""
    ans = t.answers
    scenes = manifest["scenes"] if manifest else list(dict.fromkeys(a["scene"] for a in ans))
    others = manifest["comparisons"] if manifest else list(dict.fromkeys(a["other"] for a in ans if not is_catch(a)))
    questions = [q["id"] for q in manifest["questions"]] if manifest else list(QUESTIONS)
    ours = manifest["ours"] if manifest else (ans[0]["ours"] if ans else "full")
    rows = []
    for q in questions:
        for other in others:
            for scene in scenes + (["All"] if len(scenes) > 1 else []):
                sel = [a for a in ans if a["question"] == q and a["other"] == other
                       and (scene == "All" or a["scene"] == scene)]
                k, n = sum(prefers_ours(a) for a in sel), len(sel)
                lo, hi = interval(k, n, opts.ci, opts.level) if n else (None, None)
                per: dict[str, list[int]] = defaultdict(lambda: [0, 0])
                for a in sel:
                    per[a["participant"]][0] += prefers_ours(a)
                    per[a["participant"]][1] += 1
                clo, chi = (cluster_bootstrap([v[0] for v in per.values()], [v[1] for v in per.values()],
                                              opts.level) if n else (None, None))
                rows.append({"question": q, "scene": scene, "ours": ours, "other": other, "prefer_ours": k,
                             "answers": n, "participants": len(per), "rate": k / n if n else None,
                             "ci_low": lo, "ci_high": hi, "ci_method": opts.ci, "level": opts.level,
                             "p_binomial": binomial_p(k, n) if n else None,
                             "cluster_ci_low": clo, "cluster_ci_high": chi})
    return rows


@dataclass
class RateCell(Cell):
    """A preference rate in percent with its interval and answer count."""

    lo: float = 0.0
    hi: float = 0.0
    n: int = 0

    def text(self) -> str:
        if self.value is None:
            return "n/a"
        return f"{100 * self.value:.1f} [{100 * self.lo:.1f}, {100 * self.hi:.1f}] n={self.n}"


def table4(t: Tally, manifest: dict[str, Any] | None, opts: TallyOptions) -> Table:
    """Table 4 in the paper's layout: question blocks, 'Ours vs X' rows, scenes (+ All) as columns."""
    labels = (manifest or {}).get("labels", {})
    scenes = list(dict.fromkeys(r["scene"] for r in t.rows))
    ci = "Wilson score" if opts.ci == "wilson" else "Clopper-Pearson"
    tab = Table("table4_user_study", f"User study (2AFC): answers preferring ours, in % "
                f"[{100 * opts.level:g}% {ci} interval], n answers", ["Preference for ours"] + scenes)
    by = {(r["question"], r["other"], r["scene"]): r for r in t.rows}
    for q in dict.fromkeys(r["question"] for r in t.rows):
        tab.sections[len(tab.rows)] = QUESTIONS.get(q, (q, q))[1]
        for other in dict.fromkeys(r["other"] for r in t.rows):
            cells: list[Cell] = []
            for s in scenes:
                r = by[(q, other, s)]
                if r["answers"]:
                    bold = r["ci_low"] > 0.5 or r["ci_high"] < 0.5
                    cells.append(RateCell(r["rate"], bold=bold, lo=r["ci_low"], hi=r["ci_high"], n=r["answers"]))
                else:
                    cells.append(Cell(None, tab.note("no valid answers for this comparison and scene")))
            tab.rows.append((f"Ours vs {labels.get(other) or default_label(other)}", cells))
    reasons = Counter(e.reason for e in t.exclusions)
    used = {a["participant"] for a in t.answers}
    tab.footnotes.append("Bold: the interval excludes 50%. Intervals treat answers as independent; answers of "
                         "one participant are not, so they are optimistic when participants disagree (the long CSV "
                         "adds a participant bootstrap interval)")
    bias = side_bias(t.answers)
    if bias["answers"]:
        tab.footnotes.append(f"Side bias: the left video was chosen in {100 * bias['rate']:.1f}% of the answers "
                             f"[{100 * bias['ci'][0]:.1f}, {100 * bias['ci'][1]:.1f}]; sides are counterbalanced "
                             "per participant")
    if t.catch or reasons["failed_catch"]:
        failed = len({e.participant for e in t.exclusions if e.reason == "failed_catch"})
        tab.footnotes.append(f"Attention checks (ours against a blurred copy; not in the table): "
                             f"{_n(len({a['participant'] for a in t.catch}), 'participant')} passed, "
                             f"{failed} failed and excluded")
    tab.footnotes.append(f"{_n(len(used), 'participant')} and {_n(len(t.answers), 'answer')} used; "
                         f"{_n(len(t.participants_seen) - len(used), 'participant')} and "
                         f"{_n(len(t.exclusions), 'answer')} excluded"
                         + (": " + ", ".join(f"{REASON_LABELS[r]} {reasons[r]}" for r in REASONS if reasons[r])
                            if reasons else ""))
    return tab


def _n(k: int, word: str) -> str:
    return f"{k} {word}{'' if k == 1 else 's'}"


def long_csv(rows: Sequence[dict[str, Any]]) -> str:
    buf = io.StringIO()
    cols = list(rows[0]) if rows else ["question"]
    w = csv.DictWriter(buf, cols, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    return buf.getvalue()


def exclusions_csv(excl: Sequence[Exclusion]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["source", "reason", "detail", "participant", "pair", "question"])
    for e in excl:
        w.writerow([e.source, e.reason, e.detail, e.participant, e.pair, e.question])
    return buf.getvalue()


def tally(paths: Sequence[str | Path], manifest: dict[str, Any] | None = None,
          opts: TallyOptions | None = None) -> tuple[Tally, Table]:
    """Read, exclude, count: the tally and Table 4."""
    opts = opts or TallyOptions()
    interval(1, 2, opts.ci, opts.level)  # an unknown interval or level fails before any work
    records, bad = read_answer_files(paths)
    t = select_answers(records, manifest, opts, bad)
    t.rows = tally_rows(t, manifest, opts)
    t.records = records
    return t, table4(t, manifest, opts)


def write_tally(t: Tally, table: Table, out_dir: str | Path, opts: TallyOptions) -> list[Path]:
    """table4_user_study.{csv,md,tex}, the long CSV, the exclusions CSV and a JSON summary."""
    out = Path(out_dir)
    files = {f"{table.name}.csv": to_csv(table), f"{table.name}.md": to_markdown(table),
             f"{table.name}.tex": to_latex(table), f"{table.name}_long.csv": long_csv(t.rows),
             "table4_exclusions.csv": exclusions_csv(t.exclusions),
             "table4_participants.csv": participants_csv(t.records, t)}
    for name, text in files.items():
        atomic_write_text(out / name, text)
    write_json(out / f"{table.name}.json", {
        "options": asdict(opts), "participants_seen": len(t.participants_seen),
        "participants_used": len({a["participant"] for a in t.answers}), "answers_used": len(t.answers),
        "excluded": dict(Counter(e.reason for e in t.exclusions)), "catch_answers": len(t.catch),
        "side_bias": side_bias(t.answers), "rows": t.rows})
    return [out / n for n in files] + [out / f"{table.name}.json"]
