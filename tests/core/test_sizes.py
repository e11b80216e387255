"""Library size limits (issue 25): no module of ``anigs/`` outside ``anigs/stages/`` over 400 lines,
no function or method there over 120 lines. ``python tests/core/test_sizes.py`` lists the largest."""
from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2] / "anigs"
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 120


def library_modules() -> list[Path]:
    """Every ``.py`` of the library, stages excluded (they have their own, smaller limit)."""
    return sorted(p for p in ROOT.rglob("*.py") if "stages" not in p.relative_to(ROOT).parts)


def module_lines(path: Path) -> int:
    return len(path.read_text().splitlines())


def function_sizes(path: Path) -> list[tuple[str, int]]:
    """(qualified name, lines from ``def`` to its last line, decorators excluded) per function."""
    out: list[tuple[str, int]] = []

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    out.append((name, child.end_lineno - child.lineno + 1))
                walk(child, name + ".")
            else:
                walk(child, prefix)

    walk(ast.parse(path.read_text(), str(path)), "")
    return out


def test_the_checker_sees_functions_and_methods(tmp_path):
    src = tmp_path / "m.py"
    src.write_text("class A:\n    def f(self):\n        def g():\n            pass\n        return 1\n\n\ndef h():\n    pass\n")
    assert dict(function_sizes(src)) == {"A.f": 4, "A.f.g": 2, "h": 2}
    assert module_lines(src) == 9
    assert len(library_modules()) > 50 and not any("stages" in p.parts for p in library_modules())


def test_no_library_module_over_the_limit():
    big = {str(p.relative_to(ROOT.parent)): n for p in library_modules() if (n := module_lines(p)) > MAX_MODULE_LINES}
    assert not big, f"modules over {MAX_MODULE_LINES} lines (split them by concept): {big}"


def test_no_library_function_over_the_limit():
    big = {f"{p.relative_to(ROOT.parent)}:{name}": n for p in library_modules()
           for name, n in function_sizes(p) if n > MAX_FUNCTION_LINES}
    assert not big, f"functions over {MAX_FUNCTION_LINES} lines (extract steps): {big}"


if __name__ == "__main__":
    top = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    mods = sorted(((module_lines(p), str(p.relative_to(ROOT.parent))) for p in library_modules()), reverse=True)
    funcs = sorted(((n, f"{p.relative_to(ROOT.parent)}:{name}") for p in library_modules()
                    for name, n in function_sizes(p)), reverse=True)
    print(f"largest modules (limit {MAX_MODULE_LINES}):")
    print("\n".join(f"  {n:5d} {p}" for n, p in mods[:top]))
    print(f"largest functions (limit {MAX_FUNCTION_LINES}):")
    print("\n".join(f"  {n:5d} {p}" for n, p in funcs[:top]))
