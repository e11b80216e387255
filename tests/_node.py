"""Third-party npm tools for the interoperability tests: node, and the pinned packages that
``envs/npm.sh`` installs into ``.node/`` (splat-transform, Spark, three.js, gltf-validator).
Tests skip when a piece is missing; with ANIGS_REQUIRE_BROWSER=1 (CI) a missing one is an error.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MODULES = ROOT / ".node" / "node_modules"
NODE = shutil.which("node")
PACKAGES = {"splat-transform": "@playcanvas/splat-transform", "spark": "@sparkjsdev/spark", "three": "three",
            "gltf-validator": "gltf-validator", "playcanvas": "playcanvas"}


def missing(*names: str) -> list[str]:
    """The pieces of ``names`` (keys of :data:`PACKAGES`) and node that are not installed."""
    out = [] if NODE else ["node"]
    return out + [PACKAGES[n] for n in names if not (MODULES / PACKAGES[n] / "package.json").is_file()]


def needs_node(*names: str):
    """Skip marker for a test that runs these npm packages (an error under ANIGS_REQUIRE_BROWSER=1)."""
    gone = missing(*names)
    if gone and os.environ.get("ANIGS_REQUIRE_BROWSER") == "1":
        raise RuntimeError(f"ANIGS_REQUIRE_BROWSER=1 but {', '.join(gone)} missing (bash envs/npm.sh)")
    return pytest.mark.skipif(bool(gone), reason=f"needs {', '.join(gone)}: run `bash envs/npm.sh` "
                                                 "(node and npm, then pinned packages into .node/)")


def version(name: str) -> str:
    return json.loads((MODULES / PACKAGES[name] / "package.json").read_text())["version"]


def splat_transform(*args: str, timeout: float = 300) -> str:
    """Run splat-transform's command line (``-w`` overwrite, quiet); returns its stdout."""
    cli = MODULES / PACKAGES["splat-transform"] / "bin" / "cli.mjs"
    res = subprocess.run([NODE, str(cli), "-q", "-w", *map(str, args)], capture_output=True, text=True,
                         timeout=timeout)
    assert res.returncode == 0, f"splat-transform {' '.join(map(str, args))}: {res.stderr[-2000:]}"
    return res.stdout


def node_script(source: str, *args: str, timeout: float = 120) -> str:
    """Run an ES module ``source`` with node in ``.node/`` (so its imports resolve); returns stdout."""
    script = MODULES.parent / f".anigs-test-{os.getpid()}.mjs"
    script.write_text(source)
    try:
        res = subprocess.run([NODE, str(script), *map(str, args)], capture_output=True, text=True, timeout=timeout,
                             cwd=MODULES.parent)
    finally:
        script.unlink()
    assert res.returncode == 0, res.stderr[-2000:]
    return res.stdout
