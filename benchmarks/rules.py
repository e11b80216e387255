"""Where a Snakemake run's time went, rule by rule, from the benchmark TSVs its ``benchmark:``
directives wrote (``results/{scene}/benchmarks/static.tsv``,
``results/{scene}/{variant}/benchmarks/round{r}/render_clip_{view}.tsv``, ...).

    python benchmarks/rules.py [RESULTS] [--compare BEFORE] [--json OUT]

RESULTS (default ``results/``) may be any folder of the tree (``results/demo/full``): every ``*.tsv``
inside a ``benchmarks`` folder under it counts. The rule is the file name without ``.tsv`` and a
view suffix ``_v<digits>`` (``render_clip_v03`` -> ``render_clip``; ``round2/update.tsv`` -> ``update``).
Per rule: jobs, wall seconds and CPU seconds (sums over jobs of each job's mean over
--benchmark-repeats; CPU seconds stay comparable when other work shared the machine) and peak
memory (the largest ``max_rss``, MB), the most wall time first, then the total. ``--compare BEFORE``
prints BEFORE's figures beside RESULTS' and the ratios RESULTS / BEFORE (< 1: faster now).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from anigs.reports.benchmark_tsv import benchmark_files, breakdown_total, compare_breakdowns, rule_breakdown  # noqa: E402


def _f(x, fmt: str = ".1f") -> str:
    return "n/a" if x is None else format(x, fmt)


def _table(head: list[str], rows: list[list[str]]) -> str:
    w = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]

    def line(cells: list[str]) -> str:
        return "  ".join(c.ljust(w[0]) if i == 0 else c.rjust(w[i]) for i, c in enumerate(cells))

    return "\n".join([line(head), line(["-" * n for n in w])] + [line(r) for r in rows])


def breakdown_table(rows: list[dict]) -> str:
    total = breakdown_total(rows)
    all_s = total["seconds"] or 1.0
    cells = [[r["rule"], str(r["jobs"]), _f(r["seconds"]), f"{100 * r['seconds'] / all_s:.1f}",
              _f(r["cpu_seconds"]), _f(r["max_rss_mb"], ".0f")] for r in rows + [total]]
    return _table(["rule", "jobs", "wall s", "wall %", "CPU s", "peak RSS MB"], cells)


def compare_table(rows: list[dict]) -> str:
    def jobs(r):
        b, a = r["jobs_before"], r["jobs_after"]
        return f"{'-' if b is None else b}/{'-' if a is None else a}"

    cells = [[r["rule"], jobs(r), _f(r["seconds_before"]), _f(r["seconds_after"]), _f(r["seconds_ratio"], ".2f"),
              _f(r["cpu_seconds_before"]), _f(r["cpu_seconds_after"]), _f(r["cpu_seconds_ratio"], ".2f")]
             for r in rows]
    return _table(["rule", "jobs b/a", "wall s before", "wall s after", "after/before",
                   "CPU s before", "CPU s after", "after/before"], cells)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", nargs="?", default="results",
                    help="results folder of a Snakemake run (default results/)")
    ap.add_argument("--compare", metavar="BEFORE", help="an earlier run's results folder: before / after per rule")
    ap.add_argument("--json", metavar="OUT", help="also write the table(s) as JSON")
    args = ap.parse_args(argv)

    def load(root: str) -> list[dict]:
        files = benchmark_files(root)
        if not files:
            raise SystemExit(f"{root}: no benchmark TSVs (*.tsv inside a benchmarks/ folder)")
        return rule_breakdown(files)

    after = load(args.results)
    out: dict = {"results": args.results, "rules": after, "total": breakdown_total(after)}
    print(f"{args.results}: {out['total']['jobs']} jobs")
    print(breakdown_table(after))
    if args.compare:
        before = load(args.compare)
        cmp = (compare_breakdowns(before, after)
               + compare_breakdowns([breakdown_total(before)], [breakdown_total(after)]))
        print(f"\nbefore: {args.compare}, after: {args.results}")
        print(compare_table(cmp))
        out.update(before=args.compare, before_rules=before, before_total=breakdown_total(before), compare=cmp)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
