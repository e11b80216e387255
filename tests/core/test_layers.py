"""The library does not know the stages (issue 50): no module of ``anigs/`` below the stages' layer
(:data:`benchmarks.import_graph.LAYERS`: metrics, reports, the scene and animation packages, the base)
imports ``anigs.stages`` in any form: at module level, inside a function, under ``if TYPE_CHECKING:``,
relatively (``from ..stages import x``, ``from .. import stages``) or through ``importlib.import_module``
with a literal name. Read with ``ast``: nothing is imported.

A library function that reads a stage's folder types it by a protocol of :mod:`anigs.contract`
(:class:`~anigs.contract.CaptureFiles`, :class:`~anigs.contract.MaskFiles`), which the stage's
``Outputs`` satisfies; the last tests check that they still do."""
from __future__ import annotations

import ast
import inspect
from pathlib import Path

import anigs
from anigs.contract import CaptureFiles, MaskFiles
from benchmarks.import_graph import LAYERS, module_name, package_of

ROOT = Path(anigs.__file__).parent
STAGES_LAYER = next(i for i, (_, pkgs) in enumerate(LAYERS) if "stages" in pkgs)
ABOVE = {p for _, pkgs in LAYERS[STAGES_LAYER:] for p in pkgs}  # stages and what may import them (cli)


def _named(node: ast.AST, package: str) -> list[str]:
    """The modules an import statement (or an ``import_module``/``__import__`` call on a literal) names."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if isinstance(node, ast.ImportFrom):
        parts = package.split(".")
        base = parts[:len(parts) - node.level + 1] if node.level else []
        source = ".".join([*base, *([node.module] if node.module else [])])
        return [source, *(f"{source}.{a.name}" for a in node.names)]
    if isinstance(node, ast.Call) and node.args:
        f = node.func
        callee = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
        arg = node.args[0]
        if isinstance(arg, ast.JoinedStr) and arg.values:  # f"anigs.stages.{name}"
            arg = arg.values[0]
        if callee in ("import_module", "__import__") and isinstance(arg, ast.Constant) and isinstance(arg.value, str):
            return [arg.value]
    return []


def stage_imports(root: Path, skip: set[str]) -> list[str]:
    """``module:line: name`` for every import of ``<top>.stages`` (or a module under it) by a module of the
    package at ``root`` whose top-level package (:func:`~benchmarks.import_graph.package_of`) is not in
    ``skip``; every import statement counts, wherever it sits."""
    top = root.name
    stages = f"{top}.stages"
    out = []
    for path in sorted(root.rglob("*.py")):
        here = module_name(path, root)
        if package_of(here, top) in skip:
            continue
        package = here if path.name == "__init__.py" else here.rpartition(".")[0]
        hits = []
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            hit = [n for n in _named(node, package) if n == stages or n.startswith(stages + ".")]
            if hit:
                hits.append((node.lineno, hit[0]))
        out += [f"{here}:{line}: {name}" for line, name in sorted(hits)]
    return out


def test_the_library_imports_no_stage_module():
    checked = {package_of(module_name(p, ROOT), ROOT.name) for p in ROOT.rglob("*.py")} - ABOVE
    assert {"metrics", "reports", "baselines", "render", "static", "effects", "views", "masks", "animate",
            "refine", "export", "viewer", "contract"} <= checked
    found = stage_imports(ROOT, ABOVE)
    assert found == [], ("library modules import the stages (type the argument by a protocol of "
                         f"anigs.contract instead): {found}")


def test_the_check_finds_every_form(tmp_path):
    pkg = tmp_path / "pkg"
    for d in ("stages", "lib", "cli"):
        (pkg / d).mkdir(parents=True)
        (pkg / d / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "stages" / "masks.py").write_text("class Outputs: pass\n")
    (pkg / "lib" / "a.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from pkg.stages.masks import Outputs\n"          # 3
        "def f():\n    import pkg.stages.masks\n"                                 # 5
        "from ..stages import masks\n"                                            # 6
        "from .. import stages\n"                                                 # 7
        "import importlib\nimportlib.import_module('pkg.stages.masks')\n"        # 9
        "def g(n):\n    return importlib.import_module(f'pkg.stages.{n}')\n"      # 11
        "from pkg import lib\nimport pkg.stagesque\nfrom . import stages_doc\n")  # none of these
    (pkg / "cli" / "run.py").write_text("from pkg.stages import masks\n")  # the command line may
    (pkg / "stages" / "b.py").write_text("from pkg.stages import masks\n")  # and the stages themselves
    assert stage_imports(pkg, {"stages", "cli"}) == [
        "pkg.lib.a:3: pkg.stages.masks", "pkg.lib.a:5: pkg.stages.masks", "pkg.lib.a:6: pkg.stages",
        "pkg.lib.a:7: pkg.stages", "pkg.lib.a:9: pkg.stages.masks", "pkg.lib.a:11: pkg.stages."]


def _members(protocol: type) -> list[str]:
    return sorted({n for n in [*vars(protocol), *protocol.__annotations__] if not n.startswith("_")})


def _parameters(method) -> list[tuple]:
    return [(p.name, p.kind, p.default) for p in inspect.signature(method).parameters.values()]


def _satisfies(impl: type, protocol: type, tmp_path: Path) -> list[str]:
    """What ``impl`` (an ``Outputs`` type) lacks of ``protocol``: a member, or a method's parameters."""
    obj, wrong = impl(tmp_path), []
    for name in _members(protocol):
        if not hasattr(obj, name):
            wrong.append(f"{impl.__module__}.{impl.__name__} has no {name}")
        elif callable(getattr(protocol, name, None)):
            if _parameters(getattr(impl, name)) != _parameters(getattr(protocol, name)):
                wrong.append(f"{impl.__module__}.{impl.__name__}.{name}{inspect.signature(getattr(impl, name))}")
    return wrong


def test_the_stage_outputs_satisfy_the_protocols(tmp_path):
    from anigs.stages.capture import Outputs as CaptureOutputs
    from anigs.stages.masks import Outputs as MasksOutputs

    assert _members(CaptureFiles) == ["gt_anchors", "gt_cameras", "gt_gaussians", "gt_labels", "gt_motion"]
    assert _members(MaskFiles) == ["effect_masks", "has_view_mask", "root", "view_mask"]
    assert _satisfies(CaptureOutputs, CaptureFiles, tmp_path) == []
    assert _satisfies(MasksOutputs, MaskFiles, tmp_path) == []
