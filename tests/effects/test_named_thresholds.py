"""No numeric threshold of the effects detector lives inline (issue 49): every number a function of
``anigs/effects`` compares with, sizes a kernel with, weighs or takes a quantile at is a config field
(``anigs/effects/config.py`` and the rules' dataclasses) or a named module-level constant
with a comment saying what it is and its unit (``MIN_POINTS = 10  # no plane is fitted to fewer points``).

What the check reads: every numeric literal inside a function (``def``, ``async def`` or ``lambda``,
methods included) of ``anigs/effects/**/*.py``. A function's decorators and default argument values
count as its own: a default is the value the code runs with whenever a caller leaves it out, so it is
named too (``min_share: float = SHOWN``, ``@lru_cache(maxsize=LOOKUP_CACHE)``). Module-level
constants and class-body assignments (dataclass field defaults) are where the numbers live: not read.

What passes inline, the arithmetic identities:

- ``0``, ``1`` (and ``-1``, ``1.0``), ``2`` (halving, doubling, squaring, ``2 * r + 1``), ``3`` (RGB
  channels, 3-D points, three features per render pass), ``100`` (percent), ``255`` (uint8);
- a nonzero literal no larger than ``EPSILON``: a guard against a division by zero (``1e-9``);
- the digits of ``round(x, 4)`` / ``array.round(3)``: a report's precision, no decision.

Values of that list can still be thresholds (``areas >= 2``, ``min_pixels=100``): those are named by
judgement, the check cannot tell them from an identity. Not read: ``config.py`` (the fields themselves),
``overview.py`` (drawing: font scales, margins and tints, no decision) and ``segmenter_tiny.py`` (the layer
sizes of a random test model).
"""
from __future__ import annotations

import ast
from pathlib import Path

import anigs

ROOT = Path(anigs.__file__).parent / "effects"
#: module (relative to the package folder) -> why its functions' numbers are not read
NOT_READ = {
    "config.py": "the configuration: its fields are the thresholds",
    "overview.py": "drawing sizes, margins and tints of the overview PNG: no decision",
    "segmenter_tiny.py": "the layer sizes of a random test segmenter: no decision",
}
IDENTITIES = frozenset({0, 1, 2, 3, 100, 255})
EPSILON = 1e-6  # a nonzero literal up to this small guards a division


def _round_digits(tree: ast.AST) -> set[int]:
    """ids of the literals that are the digits of a ``round(x, n)`` or ``x.round(n)`` call."""
    out = set()
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        if isinstance(node.func, ast.Name) and node.func.id == "round":
            digits = node.args[1:]
        elif isinstance(node.func, ast.Attribute) and node.func.attr == "round":
            digits = node.args[:1]
        else:
            continue
        digits = [*digits, *(k.value for k in node.keywords if k.arg in ("ndigits", "decimals"))]
        out.update(id(d) for d in digits if isinstance(d, ast.Constant))
    return out


def _identity(value: int | float | complex) -> bool:
    return value in IDENTITIES or 0 < abs(value) <= EPSILON


def inline_numbers(root: Path, not_read=NOT_READ) -> list[str]:
    """``module:line: value (in function)`` for every numeric literal other than an identity inside a
    function of the modules under ``root`` (module docstring)."""
    out = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if rel in not_read:
            continue
        tree = ast.parse(path.read_text(), str(path))
        digits, seen = _round_digits(tree), set()
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            for node in ast.walk(fn):
                if (isinstance(node, ast.Constant) and type(node.value) in (int, float, complex)
                        and id(node) not in seen and id(node) not in digits and not _identity(node.value)):
                    seen.add(id(node))
                    out.append(f"{rel}:{node.lineno}: {node.value!r} (in {getattr(fn, 'name', 'lambda')})")
    return sorted(set(out), key=lambda s: (s.split(":")[0], int(s.split(":")[1]), s))


def test_no_threshold_of_the_effects_detector_is_inline():
    found = inline_numbers(ROOT)
    assert found == [], ("numbers inside functions: name each as a module constant with its meaning and unit "
                         "(or a config field)\n" + "\n".join(found))


def test_the_check_finds_inline_numbers(tmp_path):
    (tmp_path / "rules").mkdir()
    (tmp_path / "config.py").write_text("def f(x):\n    return x > 0.7\n")  # not read
    (tmp_path / "a.py").write_text(
        "from dataclasses import dataclass\n"
        "from functools import lru_cache\n"
        "LIMIT = 0.8  # a module constant: fine\n"
        "@dataclass\n"
        "class C:\n"
        "    share: float = 0.25  # a field default: fine\n"
        "    def method(self, x):\n"
        "        return x >= 0.15\n"                                   # line 8
        "@lru_cache(maxsize=4096)\n"                                   # line 9
        "def f(x, k=32, eps=1e-9, n=-1):\n"                            # line 10: k
        "    y = (2 * x + 1) / max(x, 1e-12) * 255 + 100 * 3 - 1.0\n"  # identities only
        "    key = lambda v: v > 16\n"                                  # line 12
        "    return round(y, 4), x.round(5), key, LIMIT, x[-1]\n"
    )
    (tmp_path / "rules" / "b.py").write_text("def g(m):\n    return max(int(0.01 * m), 4)\n")
    assert inline_numbers(tmp_path) == [
        "a.py:8: 0.15 (in method)",
        "a.py:9: 4096 (in f)",
        "a.py:10: 32 (in f)",
        "a.py:12: 16 (in f)",
        "rules/b.py:2: 0.01 (in g)",
        "rules/b.py:2: 4 (in g)",
    ]
