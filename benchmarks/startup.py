"""How much of the rounds' CPU time goes to starting processes (issue 16: under 10%).

    python benchmarks/startup.py [RESULTS=results] [--scene demo] [--variant full]

Reads a finished run: each round job's log line "start-up X s of the process's Y s CPU" (CPU the
process spent on the interpreter, imports and arguments before its work began) and its CPU: the
"chain: ... process CPU Z s" line of a round job that also trained the round's model (``anigs round
... --then update``, anigs >= 0.5), else the benchmark TSVs of the round and update jobs
(``cpu_time``; separate update jobs start the same way, so their start-up is taken as the median
round job's). Prints the share per round and overall.
"""
from __future__ import annotations

import argparse
import re
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from anigs.reports.benchmark_tsv import benchmark_seconds  # noqa: E402

LINE = re.compile(r"round (\d+): start-up ([0-9.]+) s of the process's ([0-9.]+) s CPU")
CHAIN = re.compile(r"chain: \d+ commands, process CPU ([0-9.]+) s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="?", default="results")
    ap.add_argument("--scene", default="demo")
    ap.add_argument("--variant", default="full")
    a = ap.parse_args()
    root = Path(a.results) / a.scene / a.variant
    startup: dict[int, float] = {}
    chained: dict[int, float] = {}  # round -> the whole chained job's process CPU
    for log in sorted((root / "logs").glob("round*/round.log")):
        text = log.read_text()
        for m in LINE.finditer(text):
            startup[int(m.group(1))] = float(m.group(2))
            c = CHAIN.search(text)
            if c:
                chained[int(m.group(1))] = float(c.group(1))
    if not startup:
        print(f"no round job logs with start-up figures under {root}/logs (round_jobs: round, anigs >= 0.3)")
        return 1
    per_update = statistics.median(startup.values())
    total_cpu = total_start = 0.0
    print(f"{'round':>5} {'round CPU s':>11} {'update CPU s':>12} {'start-up s':>10} {'share':>6}")
    for r in sorted(startup):
        bench = root / "benchmarks" / f"round{r}"
        rc = chained.get(r) or benchmark_seconds([bench / "round.tsv"], "cpu_time") or 0.0
        uc = benchmark_seconds([bench / "update.tsv"], "cpu_time") if (bench / "update.tsv").is_file() else 0.0
        st = startup[r] + (per_update if uc else 0.0)
        total_cpu += rc + (uc or 0.0)
        total_start += st
        print(f"{r:>5} {rc:>11.2f} {uc or 0.0:>12.2f} {st:>10.2f} {st / max(rc + (uc or 0.0), 1e-9):>6.1%}")
    print(f"total: start-up {total_start:.2f} s of the rounds' {total_cpu:.2f} s CPU = {total_start / total_cpu:.1%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
