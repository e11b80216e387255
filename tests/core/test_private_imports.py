"""Private names stay private: no module of ``anigs/`` imports an ``_underscore`` name (a function, a
constant, a class or a module) from another module. A name another module needs is public, so that its
home module says who may rely on it (``static.evaluate.render_params``, not ``_render`` borrowed by three)."""
from __future__ import annotations

import ast
from pathlib import Path

import anigs

ROOT = Path(anigs.__file__).parent


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _module_name(path: Path, root: Path) -> str:
    rel = path.relative_to(root.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def private_imports(root: Path) -> list[str]:
    """``module:line: from X import _name`` for every import of a private name from another module under
    ``root`` (a package folder)."""
    out = []
    for path in sorted(root.rglob("*.py")):
        here = _module_name(path, root)
        package = here if path.name == "__init__.py" else here.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
                source = ".".join([*base, *([node.module] if node.module else [])])
                names = [a.name for a in node.names if _private(a.name)]
                names += [p for p in (node.module or "").split(".") if _private(p)]
            elif isinstance(node, ast.Import):
                source = ""
                names = [p for a in node.names for p in a.name.split(".") if _private(p)]
            else:
                continue
            if names and source != here:
                out.append(f"{here}:{node.lineno}: from {source or '(import)'} import {', '.join(names)}")
    return out


def test_no_module_imports_a_private_name_of_another():
    assert private_imports(ROOT) == []


def test_the_check_finds_private_imports(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from pkg.sub._impl import run\n")  # a private module
    (pkg / "sub" / "_impl.py").write_text("def run(): pass\n_CACHE = {}\nfrom pkg.sub._impl import _CACHE as c\n")
    (pkg / "a.py").write_text("from pkg.b import _helper, public\nfrom .b import _other\nimport pkg.sub._impl\n")
    (pkg / "b.py").write_text("def _helper(): pass\ndef public(): pass\n_other = 1\n")
    assert private_imports(pkg) == [
        "pkg.a:1: from pkg.b import _helper",
        "pkg.a:2: from pkg.b import _other",
        "pkg.a:3: from (import) import _impl",
        "pkg.sub:1: from pkg.sub._impl import _impl",
    ]
