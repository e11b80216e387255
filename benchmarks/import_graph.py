"""The package graph of a Python package, read from the source (AST only: nothing is imported).

    python benchmarks/import_graph.py [PACKAGE_DIR]      # default: anigs/ of this checkout

Prints
* the package graph: for each package (a sub-package such as ``render``, or a top-level module
  such as ``cameras``) the packages it imports, with the number of import statements;
* package cycles: packages that import each other (directly or round a loop);
* the arrows that run back up: a package importing one of a higher layer (LAYERS below);
* import cycles between modules, once counting only imports at module level (what runs when a
  module is imported) and once counting every runtime import (module level plus imports inside
  functions): a cycle of the second kind only is *hidden* by an import inside a function;
* the share of internal import statements that sit inside functions;
* import cycles counting every import statement, those under ``if TYPE_CHECKING:`` too (type-only
  circles: nothing runs them, but a reader still has to understand one module before the other;
  ``tests/core/test_import_cycles.py`` keeps this list empty, :func:`all_cycles`).

An import statement counts once, at the first module it names: ``from anigs.x import y`` is an
edge to ``anigs.x.y`` when that is a module, else to ``anigs.x``. Imports under
``if TYPE_CHECKING:`` do not run and are left out, except in the last list. Any other package directory works as well
(for example gsplat's, to compare the share of imports inside functions); the layering applies
to anigs only.
"""
from __future__ import annotations

import argparse
import ast
import sys
from collections import Counter, defaultdict
from pathlib import Path

# Layers of anigs, bottom (0) to top; a package may import its own layer and the ones below.
# ``__init__`` (the package root: ``__version__`` and an environment default, no imports) and
# ``contract`` (the stage folders' Outputs/Inputs types, which the library's readers take) are base.
LAYERS: list[tuple[str, set[str]]] = [
    ("base: data types, IO, device, math", {
        "io", "device", "config", "configs", "typed_config", "images", "video", "flow", "cameras",
        "gaussians", "geometry", "photos", "pixels", "registry", "formats", "contract", "knob_chart",
        "__init__"}),
    ("compiled kernels: rasterizer, SSIM", {"render", "ssim", "fused_ssim", "ssim_kernel"}),
    ("scene sources: synthetic scene, photos, SfM", {"synth", "sfm", "capture"}),
    ("scene analysis: static fit, effects, views", {"static", "effects", "views"}),
    ("dynamic masks per view", {"masks"}),
    ("animation: prior, update, baselines, export", {"refine", "animate", "baselines", "export"}),
    ("evaluation", {"metrics"}),
    ("reports and apps", {"reports", "study", "viewer"}),
    ("stages", {"stages"}),
    ("command line", {"cli", "build_kernel"}),
]


def module_name(path: Path, root: Path) -> str:
    """anigs/render/cpu_backend.py -> anigs.render.cpu_backend; anigs/render/__init__.py -> anigs.render."""
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(tree: ast.Module, type_checking: bool = False):
    """Yield (node, inside_function) for every import statement that runs (and with ``type_checking``
    those under ``if TYPE_CHECKING:`` as well)."""
    def walk(node, in_func: bool):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child) and not type_checking:
                for c in child.orelse:
                    yield from walk(ast.Module(body=[c], type_ignores=[]), in_func)
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                yield child, in_func
            funcy = isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            yield from walk(child, in_func or funcy)
    yield from walk(tree, False)


def _targets(node, mod: str, is_pkg: bool, modules: set[str], top: str) -> list[str]:
    """The internal modules one import statement names (resolved as described in the docstring)."""
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        base = node.module or ""
        if node.level:
            pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
            pkg = pkg[:len(pkg) - (node.level - 1)]
            base = ".".join(pkg + ([base] if base else []))
        names = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
    out = []
    for n in names:
        if n != top and not n.startswith(top + "."):
            continue
        while n not in modules and "." in n:
            n = n.rsplit(".", 1)[0]
        if n in modules and n not in out:
            out.append(n)
    return out


def package_of(mod: str, top: str) -> str:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def scan(root: Path, type_checking: bool = False):
    """Return (modules, edges) with edges[(a, b)] = [inside_function flags, one per statement]; with
    ``type_checking`` the imports under ``if TYPE_CHECKING:`` count as well."""
    top = root.name
    files = {module_name(p, root): p for p in sorted(root.rglob("*.py"))}
    modules = set(files)
    edges: dict[tuple[str, str], list[bool]] = defaultdict(list)
    for mod, path in files.items():
        tree = ast.parse(path.read_text(), str(path))
        for node, in_func in _imports(tree, type_checking):
            for t in _targets(node, mod, path.name == "__init__.py", modules, top):
                if t != mod:
                    edges[(mod, t)].append(in_func)
    return modules, edges


def cycles(nodes: set[str], adj: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for start in sorted(nodes):
        if start in index:
            continue
        work = [(start, iter(sorted(adj.get(start, ()))))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(adj.get(w, ())))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return sorted(out)


def all_cycles(root: Path) -> list[list[str]]:
    """The import cycles between the modules of the package at ``root`` counting every import statement:
    module level, inside functions and under ``if TYPE_CHECKING:`` (sorted module names per cycle)."""
    modules, edges = scan(root, type_checking=True)
    adj: dict[str, set[str]] = defaultdict(set)
    for a, b in edges:
        adj[a].add(b)
    return cycles(modules, adj)


def layer_of(pkg: str) -> int | None:
    for i, (_, pkgs) in enumerate(LAYERS):
        if pkg in pkgs:
            return i
    return None


def back_arrows(root: Path, type_checking: bool = False) -> list[tuple[str, str, bool]]:
    """(importing module, imported module, every import inside a function) for each import of ``root``
    (anigs) that runs back up to a higher layer (:data:`LAYERS`); ``type_checking``: those under
    ``if TYPE_CHECKING:`` count too."""
    top = root.name
    out = []
    for (a, b), flags in sorted(scan(root, type_checking)[1].items()):
        la, lb = layer_of(package_of(a, top)), layer_of(package_of(b, top))
        if la is not None and lb is not None and lb > la:
            out.append((a, b, all(flags)))
    return out


def report(root: Path) -> None:
    top = root.name
    modules, edges = scan(root)
    stmts = [f for flags in edges.values() for f in flags]
    inside = sum(stmts)
    print(f"# {top}: {len(modules)} modules, {len(stmts)} internal import statements, "
          f"{inside} inside functions ({100 * inside / max(1, len(stmts)):.0f}%)")

    pk: dict[str, Counter] = defaultdict(Counter)
    for (a, b), flags in edges.items():
        pa, pb = package_of(a, top), package_of(b, top)
        if pa != pb:
            pk[pa][pb] += len(flags)
    print("\n## Package graph (package -> imported packages: import statements)")
    for p in sorted({package_of(m, top) for m in modules}):
        deps = ", ".join(f"{q}:{n}" for q, n in sorted(pk[p].items()))
        print(f"{p} -> {deps}" if deps else f"{p}")

    pk_cycles = cycles(set(pk), {a: set(b) for a, b in pk.items()})
    print(f"\n## Package cycles (packages that import each other, directly or round a loop): {len(pk_cycles)}")
    for c in pk_cycles:
        print("  " + " <-> ".join(c))

    if top == "anigs":
        print("\n## Layers (bottom first; an arrow to a higher layer runs back up)")
        for i, (name, pkgs) in enumerate(LAYERS):
            print(f"{i} {name}: {' '.join(sorted(pkgs))}")
        unknown = sorted({package_of(m, top) for m in modules if layer_of(package_of(m, top)) is None})
        if unknown:
            print(f"not in a layer: {' '.join(unknown)}")
        print("\n## Arrows that run back up (package -> higher package: importing modules)")
        back = back_arrows(root)
        for a, b, in_func in back:
            print(f"{package_of(a, top)} -> {package_of(b, top)}: {a} -> {b} "
                  f"({'in function' if in_func else 'module level'})")
        print(f"back arrows: {len(back)} module pairs; counting imports under if TYPE_CHECKING: too: "
              f"{len(back_arrows(root, type_checking=True))}")
        hub = Counter(package_of(a, top) for (a, b) in edges
                      if package_of(b, top) == "masks" and package_of(a, top) != "masks")
        print(f"packages importing masks: {dict(sorted(hub.items()))}")

    static: dict[str, set[str]] = defaultdict(set)
    runtime: dict[str, set[str]] = defaultdict(set)
    for (a, b), flags in edges.items():
        runtime[a].add(b)
        if not all(flags):
            static[a].add(b)
    at_import = cycles(modules, static)
    at_runtime = cycles(modules, runtime)
    print(f"\n## Import cycles at module level: {len(at_import)}")
    for c in at_import:
        print("  " + " <-> ".join(c))
    def is_hidden(c: list[str]) -> bool:  # no module-level cycle inside it
        return not any(set(s) <= set(c) for s in at_import)

    hidden = [c for c in at_runtime if is_hidden(c)]
    print(f"## Import cycles at run time (module level + inside functions): {len(at_runtime)}, "
          f"hidden by imports inside functions: {len(hidden)}")
    for c in at_runtime:
        print("  " + " <-> ".join(c) + ("   (hidden)" if is_hidden(c) else ""))
    every = all_cycles(root)
    print(f"## Import cycles counting every import (those under if TYPE_CHECKING: too): {len(every)}")
    for c in every:
        print("  " + " <-> ".join(c) + ("" if c in at_runtime else "   (type-only)"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("package_dir", nargs="?", default=str(Path(__file__).resolve().parents[1] / "anigs"))
    root = Path(ap.parse_args(argv).package_dir).resolve()
    if not (root / "__init__.py").is_file():
        print(f"import_graph: {root} is not a package directory (no __init__.py)", file=sys.stderr)
        return 2
    report(root)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
