"""Deterministic toy stages for the SLURM harness DAG (stdlib only).

capture:  seed -> capture.json (a list of pseudo-random integers)
refine:   capture.json + view index -> refine/{view}.bin (a hash chain, optionally slowed down)
update:   all refine/*.bin -> update.json (fan-in: combined digest and per-view digests)
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import sys
import time
from pathlib import Path


def _atomic_write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def capture(out: Path, seed: int, n: int) -> None:
    rng = random.Random(seed)
    values = [rng.randrange(1 << 30) for _ in range(n)]
    _atomic_write(out, json.dumps({"seed": seed, "values": values}, indent=1).encode())


def refine(inp: Path, out: Path, view: int, rounds: int, sleep_s: float) -> None:
    values = json.loads(inp.read_text())["values"]
    digest = hashlib.sha256(f"{view}:{values[view % len(values)]}".encode()).digest()
    chunks = []
    for _ in range(rounds):
        digest = hashlib.sha256(digest).digest()
        chunks.append(digest)
    if sleep_s > 0:  # the slow job that the fault test cancels; never changes the output
        print(f"refine view {view}: sleeping {sleep_s} s", flush=True)
        time.sleep(sleep_s)
    _atomic_write(out, b"".join(chunks))


def update(inputs: list[Path], out: Path) -> None:
    combined = hashlib.sha256()
    per_view = {}
    for p in sorted(inputs):
        data = p.read_bytes()
        combined.update(data)
        per_view[p.name] = hashlib.sha256(data).hexdigest()
    _atomic_write(out, json.dumps({"combined": combined.hexdigest(), "views": per_view}, indent=1).encode())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("capture")
    a.add_argument("--out", type=Path, required=True)
    a.add_argument("--seed", type=int, required=True)
    a.add_argument("--n", type=int, required=True)
    b = sub.add_parser("refine")
    b.add_argument("--inp", type=Path, required=True)
    b.add_argument("--out", type=Path, required=True)
    b.add_argument("--view", type=int, required=True)
    b.add_argument("--rounds", type=int, required=True)
    b.add_argument("--sleep", type=float, default=0.0)
    c = sub.add_parser("update")
    c.add_argument("--out", type=Path, required=True)
    c.add_argument("inputs", type=Path, nargs="+")
    args = ap.parse_args(argv)
    if args.cmd == "capture":
        capture(args.out, args.seed, args.n)
    elif args.cmd == "refine":
        refine(args.inp, args.out, args.view, args.rounds, args.sleep)
    else:
        update(args.inputs, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
