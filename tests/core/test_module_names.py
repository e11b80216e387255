"""Module names a newcomer can trust: no two modules of one package differ only by a plural
(``frame.py`` beside ``frames.py``), so a name says which one holds what."""
from __future__ import annotations

from pathlib import Path

import anigs

ROOT = Path(anigs.__file__).parent


def _stem(name: str) -> str:
    return name[:-1] if name.endswith("s") else name


def plural_pairs(root: Path) -> list[tuple[str, str]]:
    """(module, module) pairs of one package whose names differ only by a trailing ``s``."""
    out = []
    for pkg in [root, *(p for p in root.rglob("*") if p.is_dir() and (p / "__init__.py").exists())]:
        names = sorted({p.stem for p in pkg.glob("*.py")} | {p.name for p in pkg.iterdir()
                                                           if p.is_dir() and (p / "__init__.py").exists()})
        seen: dict[str, str] = {}
        for n in names:
            if _stem(n) in seen and seen[_stem(n)] != n:
                out.append((f"{pkg.relative_to(root.parent)}/{seen[_stem(n)]}", n))
            seen.setdefault(_stem(n), n)
    return out


def test_no_two_modules_of_a_package_differ_only_by_a_plural():
    # anigs/stages/ names its modules after the stages (the registry: one stage, one name), and the
    # stage names are the user's (rules, commands, config sections): `view` (the viewer) and `views`
    # (the view queue) stay until a stage rename
    assert [p for p in plural_pairs(ROOT) if not p[0].startswith("anigs/stages/")] == []


def test_the_check_finds_a_plural_pair(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    for f in ("__init__.py", "frame.py", "frames.py", "labels.py"):
        (pkg / f).write_text("")
    assert plural_pairs(pkg) == [("pkg/frame", "frames")]
