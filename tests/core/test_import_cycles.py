"""No import circles between the modules of ``anigs/`` (issue 50): the graph of every ``import`` and
``from ... import`` statement, read with ``ast`` (nothing is imported), counting those inside functions
and those under ``if TYPE_CHECKING:`` too. A type-only circle does not fail at import time, but a reader
still has to understand each module before the other; an import inside a function only hides one.

The graph is :func:`benchmarks.import_graph.all_cycles` (``python benchmarks/import_graph.py`` prints the
same list last). To break a circle, move what both modules need to a module both can import (a small
module of shared records), or invert the dependency (a ``Protocol`` in the lower module), rather than
moving an import into a function."""
from __future__ import annotations

from pathlib import Path

import anigs
from benchmarks.import_graph import all_cycles, back_arrows

ROOT = Path(anigs.__file__).parent

# Circles that are known and not yet broken, each with its reason. An entry must match a circle exactly
# (its sorted module names), and one that no longer exists fails too: delete it when its circle is gone.
ALLOWED: list[list[str]] = []  # none left (the effects circle went with PhotoMaps' own module)


def test_no_import_cycles_between_anigs_modules():
    found = all_cycles(ROOT)
    new = [" <-> ".join(c) for c in found if c not in ALLOWED]
    stale = [" <-> ".join(c) for c in ALLOWED if c not in found]
    assert new == [], f"import circles between anigs modules: {new}"
    assert stale == [], f"circles allowed in ALLOWED that no longer exist (delete their entries): {stale}"


def test_the_check_finds_type_only_and_hidden_cycles(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    # a type-only circle: a -> b at module level, b -> a under TYPE_CHECKING
    (pkg / "a.py").write_text("from pkg.b import B\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.a import A\nB = 1\n")
    # a circle hidden by an import inside a function, with a relative import
    (pkg / "sub" / "c.py").write_text("def f():\n    from . import d\n")
    (pkg / "sub" / "d.py").write_text("import pkg.sub.c\n")
    # no circle: e imports the package pkg.sub (its __init__), which imports nothing back
    (pkg / "e.py").write_text("from pkg.sub import c\nimport typing\n")
    assert all_cycles(pkg) == [["pkg.a", "pkg.b"], ["pkg.sub.c", "pkg.sub.d"]]


def test_no_import_runs_back_up_a_layer():
    """No package imports one of a higher layer (benchmarks/import_graph.py LAYERS: base, kernels, scene sources,
    analysis, masks, animation, evaluation, reports, stages, command line), not even for types only."""
    back = [f"{a} -> {b}" for a, b, _ in back_arrows(ROOT, type_checking=True)]
    assert back == [], f"imports that run back up a layer: {back}"
