"""Where the stages' layout file names appear outside their ``Outputs`` (issue 25's check).

    python benchmarks/layout_names.py [--all]

Takes every file name of every stage's ``Outputs.LAYOUT`` (:func:`anigs.contract.outputs_of`)
and of the study folder's (:mod:`anigs.study.layout`, not a pipeline stage) and greps anigs/, benchmarks/, workflow/ and the Snakefile for them. Hits inside a ``File(...)``
of a stage module (the contract itself), docstrings (a rule file's triple-quoted strings) and
comments are not counted; what is left is printed with the line and counted per file: string
literals in code that name a stage's file. Generic names that are also words of prose (``images``,
``gt``, ``render``, ...) are skipped. The last line is the total (the issue's grep). Exit status 0.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import io
import re
import subprocess
import tokenize
from collections import Counter
from pathlib import Path

from anigs.stages import STAGES
from anigs.contract import outputs_of

ROOT = Path(__file__).resolve().parents[1]
DIRS = ("anigs", "benchmarks", "workflow", "Snakefile")
OWNERS = ("anigs.study.layout",)  # Outputs outside anigs/stages
GENERIC = {"images", "gt", "work", "sparse", "render", "target", "clips", "slices", "logs"}


def layout_names() -> dict[str, str]:
    """file name (last path part, format fields kept) -> the stage whose Outputs names it."""
    names: dict[str, str] = {}
    modules = [(s.name, s.load()) for s in STAGES] + [(m, importlib.import_module(m)) for m in OWNERS]
    for owner, module in modules:
        for o in outputs_of(module):
            for f in o.LAYOUT.values():
                n = f.name.rstrip("/").split("/")[-1]
                if n not in GENERIC and "." in n and "{" not in n.split(".")[0]:
                    names.setdefault(n, owner)
    return names


def _contract_file(path: str) -> bool:
    """Whether ``path`` holds ``Outputs`` types (a stage module, or one of :data:`OWNERS`)."""
    return path.startswith("anigs/stages/") or path in {m.replace(".", "/") + ".py" for m in OWNERS}


def name_pattern(names) -> str:
    """A regex of ``names`` as whole file names (``labels.npy``, not ``dynamic_labels.npy``)."""
    return "(^|[^A-Za-z0-9_])(" + "|".join(re.escape(n) for n in sorted(names, key=len, reverse=True)) + ")"


def string_lines(path: Path, names: set[str]) -> set[int]:
    """Line numbers of ``path`` where a string literal (not a docstring) holds one of ``names``."""
    src, docs, found = path.read_text(), doc_lines(path), set()
    pat = re.compile(name_pattern(names))
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type == tokenize.STRING or tok.type == getattr(tokenize, "FSTRING_MIDDLE", -1):
            if tok.start[0] not in docs and pat.search(tok.string):
                found.update(range(tok.start[0], tok.end[0] + 1))
    return found


def doc_lines(path: Path) -> set[int]:
    """Line numbers of ``path`` that are docstrings or comments (a rule file, which is not Python: its
    triple-quoted strings count as docstrings)."""
    src = path.read_text()
    lines: set[int] = set()
    tokens = list(tokenize.generate_tokens(io.StringIO(src).readline))
    if path.suffix == ".py":
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)) and node.body:
                b = node.body[0]
                if isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant) and isinstance(b.value.value, str):
                    lines.update(range(b.lineno, b.end_lineno + 1))
    else:
        for tok in tokens:
            if tok.type == tokenize.STRING and tok.string.lstrip("rbuRBU").startswith(('"""', "'''")):
                lines.update(range(tok.start[0], tok.end[0] + 1))
    lines.update(tok.start[0] for tok in tokens if tok.type == tokenize.COMMENT)
    return lines


def hits(root: Path = ROOT, dirs: tuple[str, ...] = DIRS) -> tuple[dict[str, str], list[str], list[str]]:
    """(layout names, ``path:line:text`` of string literals in code that spell one outside its
    ``Outputs``, the other hits: docstrings, comments)."""
    names = layout_names()
    grep = ["grep", "-rnHE", "--include=*.py", "--include=*.smk", "--include=Snakefile", name_pattern(names), *dirs]
    out = subprocess.run(grep, cwd=root, capture_output=True, text=True).stdout.splitlines()
    cache: dict[str, set[int]] = {}  # path -> lines with a string literal naming a layout file
    code, docs = [], []
    for line in out:
        path, no, text = line.split(":", 2)
        if _contract_file(path) and "File(" in text:
            continue  # the contract itself
        if path == "benchmarks/layout_names.py":
            continue
        d = cache.setdefault(path, string_lines(root / path, set(names)))
        (code if int(no) in d else docs).append(line)
    return names, code, docs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--all", action="store_true", help="also print the docstring/comment hits per file")
    args = ap.parse_args()
    names, code, docs = hits()
    print(f"layout names ({len(names)}): {', '.join(sorted(names))}")
    print(f"\nin code outside the Outputs: {len(code)} lines")
    for line in code:
        print("  " + line[:160])
    print("\nper file:")
    for p, c in sorted(Counter(d.split(":", 1)[0] for d in code).items(), key=lambda pc: (-pc[1], pc[0])):
        print(f"  {c:4d}  {p}")
    print(f"\nelsewhere (docstrings, comments, identifiers): {len(docs)} lines in {len({d.split(':', 1)[0] for d in docs})} files")
    if args.all:
        for p, c in sorted(Counter(d.split(":", 1)[0] for d in docs).items()):
            print(f"  {p}: {c}")
    outside = sum(not d.startswith("anigs/stages/") for d in code)
    print(f"\ntotal: {len(code)} code lines spell a layout file name outside its Outputs "
          f"({len(code) - outside} in anigs/stages, {outside} elsewhere)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
