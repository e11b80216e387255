"""Where two results trees of the same config part ways: the first stage (pipeline order) whose
artifacts differ, and copies of both trees kept for a look after the test's tmp folders are gone.

Used by the workflow tests that compare two runs (``test_interrupted_run_resumes_to_the_same_artifacts``).
A key is a path relative to the results root: ``<scene>/<stage folder>/...`` for scene stages,
``<scene>/<variant>/<folder>/...`` for variant stages (``round<N>`` folders are the animate loop).
"""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

from anigs.stages import STAGES

ROOT = Path(__file__).resolve().parents[2]
ORDER = [s.name for s in STAGES]
FOLDER_STAGE = {"viewer": "view", "clips": "final", "slices": "final"}  # folders not named after their stage


def stage_of(key: str) -> tuple[int, int, str]:
    """Sort key and name of the stage that wrote ``key``: (pipeline index, round, name); folders
    the registry does not know sort last, under their own name."""
    parts = Path(key).parts
    for part in parts[1:-1]:
        if part.startswith("round") and part[5:].isdigit():
            return ORDER.index("animate"), int(part[5:]), part
        name = FOLDER_STAGE.get(part, part)
        if name in ORDER:
            return ORDER.index(name), 0, name
    return len(ORDER), 0, parts[1] if len(parts) > 2 else key


def first_stage(keys) -> str | None:
    """The earliest stage (pipeline order, then round) among the differing ``keys``; None if none."""
    return min((stage_of(k) for k in keys), default=(0, 0, None))[2]


def by_stage(keys) -> dict[str, list[str]]:
    """The differing keys grouped by stage, stages in pipeline order."""
    out: dict[str, list[str]] = {}
    for k in sorted(keys, key=lambda k: (stage_of(k), k)):
        out.setdefault(stage_of(k)[2], []).append(k)
    return out


def json_differences(a: Path, b: Path) -> list[str]:
    """The .json files of both trees whose content differs once the two roots and timings are
    normalised (``benchmarks/compare_results.py``'s rule); logs and benchmarks skipped."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import compare_results
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    fa, fb = compare_results.files(a), compare_results.files(b)
    roots = [str(a), str(b)]
    return [k for k in sorted(set(fa) & set(fb)) if k.endswith(".json")
            and not compare_results.same_content(fa[k], fb[k], roots)]


def keep_trees(trees: dict[str, Path], fallback: Path) -> Path:
    """Copy each results tree (logs included) to ``$ANIGS_KEEP_FAILED/<name>`` (or ``fallback/<name>``
    when the variable is unset) and return the folder that holds them."""
    dest = Path(os.environ.get("ANIGS_KEEP_FAILED") or fallback)
    for name, src in trees.items():
        target = dest / name
        if target.exists():
            shutil.rmtree(target)
        shutil.copytree(src, target, symlinks=True, ignore_dangling_symlinks=True)
    return dest


def report(different, a: Path, b: Path, kept: Path) -> str:
    """A failure message: the first differing stage, every differing artifact by stage, the JSON
    files that differ too, and where the two trees were kept."""
    lines = [f"first differing stage: {first_stage(different)}"]
    for stage, keys in by_stage(different).items():
        lines.append(f"  {stage}: {len(keys)} artifact(s): {', '.join(keys[:8])}{' ...' if len(keys) > 8 else ''}")
    try:
        js = json_differences(a, b)
    except Exception as exc:  # the diagnosis must not hide the failure it explains
        js = [f"(json comparison failed: {type(exc).__name__}: {exc})"]
    lines.append(f"  json files that differ too: {', '.join(js) if js else 'none'}")
    lines.append(f"both trees kept under {kept}")
    return "\n".join(lines)
