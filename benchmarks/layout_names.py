"""Where the stages' layout file names appear outside their ``Outputs`` (issue 25's check).

    python benchmarks/layout_names.py [--all]

Takes every file name of every stage's ``Outputs.LAYOUT`` (:func:`anigs.stages.contract.outputs_of`)
and greps anigs/, benchmarks/, workflow/ and the Snakefile for them. Hits inside a ``File(...)``
of a stage module (the contract itself), docstrings and comments are not counted; what is left is
printed by file with the line: string literals in code that name another stage's file. Generic
names that are also words of prose (``images``, ``gt``, ``render``, ...) are skipped. Exit status 0;
the count is the figure.
"""

from __future__ import annotations

import argparse
import ast
import io
import re
import subprocess
import tokenize
from collections import Counter
from pathlib import Path

from anigs.stages import STAGES
from anigs.stages.contract import outputs_of

ROOT = Path(__file__).resolve().parents[1]
GENERIC = {"images", "gt", "work", "sparse", "render", "target", "clips", "slices", "logs"}


def layout_names() -> dict[str, str]:
    """file name (last path part, format fields kept) -> the stage whose Outputs names it."""
    names: dict[str, str] = {}
    for s in STAGES:
        for o in outputs_of(s.load()):
            for f in o.LAYOUT.values():
                n = f.name.rstrip("/").split("/")[-1]
                if n not in GENERIC and "." in n and "{" not in n.split(".")[0]:
                    names.setdefault(n, s.name)
    return names


def string_lines(path: Path, names: set[str]) -> set[int]:
    """Line numbers of ``path`` where a string literal (not a docstring) holds one of ``names``."""
    src, docs, found = path.read_text(), doc_lines(path), set()
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type == tokenize.STRING or tok.type == getattr(tokenize, "FSTRING_MIDDLE", -1):
            if tok.start[0] not in docs and any(n in tok.string for n in names):
                found.update(range(tok.start[0], tok.end[0] + 1))
    return found


def doc_lines(path: Path) -> set[int]:
    """Line numbers of ``path`` that are docstrings or comments."""
    src = path.read_text()
    lines: set[int] = set()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)) and node.body:
            b = node.body[0]
            if isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant) and isinstance(b.value.value, str):
                lines.update(range(b.lineno, b.end_lineno + 1))
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type == tokenize.COMMENT:
            lines.add(tok.start[0])
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--all", action="store_true", help="also print the docstring/comment hits per file")
    args = ap.parse_args()
    names = layout_names()
    pat = "|".join(re.escape(n) for n in sorted(names, key=len, reverse=True))
    grep = ["grep", "-rnE", "--include=*.py", "--include=*.smk", pat, "anigs", "benchmarks", "workflow", "Snakefile"]
    out = subprocess.run(grep, cwd=ROOT, capture_output=True, text=True).stdout.splitlines()
    cache: dict[str, set[int]] = {}  # path -> lines with a string literal naming a layout file
    code, docs = [], []
    for line in out:
        path, no, text = line.split(":", 2)
        if path.startswith("anigs/stages/") and "File(" in text:
            continue  # the contract itself
        if path == "benchmarks/layout_names.py":
            continue
        if path.endswith(".py"):
            d = cache.setdefault(path, string_lines(ROOT / path, set(names)))
            (code if int(no) in d else docs).append(line)
        else:
            (docs if text.strip().startswith("#") else code).append(line)
    print(f"layout names ({len(names)}): {', '.join(sorted(names))}")
    print(f"\nin code outside the Outputs: {len(code)} lines")
    for line in code:
        print("  " + line[:160])
    print(f"\nelsewhere (docstrings, comments, identifiers): {len(docs)} lines in {len({d.split(':', 1)[0] for d in docs})} files")
    if args.all:
        for p, c in sorted(Counter(d.split(":", 1)[0] for d in docs).items()):
            print(f"  {p}: {c}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
