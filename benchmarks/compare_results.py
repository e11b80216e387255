"""Compare two results trees artifact by artifact: byte-identical, the same content once paths and
wall times are normalised, or different (for refactors that must not change any artifact).

    python benchmarks/compare_results.py BEFORE/results/demo AFTER/results/demo [ROOT_BEFORE ROOT_AFTER ...]

ROOTs are path prefixes replaced by a placeholder inside JSON and clip metadata (the results root
of each run, when they differ). .json are compared as data, .npz array by array (metadata as JSON),
.pt tensor by tensor, the viewer's compact scene (.anigs, and scene.js that embeds it in base64) by
its JSON header and its payload; logs/ and benchmarks/ are skipped (timings).
"""
from __future__ import annotations

import argparse
import base64
import hashlib
import json
import struct
from pathlib import Path

import numpy as np

SKIP_DIRS = {"logs", "benchmarks"}
SKIP_KEYS = {"seconds", "timings_s", "seconds_per_step", "cpu_s", "cpu_seconds", "load_average", "eval_seconds",
             "fit_seconds", "train_seconds", "train_cpu_seconds", "step_ms_median", "step_ms_median_final",
             "minutes", "estimated_minutes", "estimated_seconds", "estimate_ratio"}  # (this machine's minutes)


def _norm(x, roots: list[str]):
    if isinstance(x, str):
        for r in roots:
            x = x.replace(r, "<ROOT>")
        return x
    if isinstance(x, dict):
        return {k: _norm(v, roots) for k, v in x.items() if k not in SKIP_KEYS}
    if isinstance(x, list):
        return [_norm(v, roots) for v in x]
    return x


def _json_of(arr: np.ndarray):
    try:
        return json.loads(bytes(arr).decode() if arr.dtype == np.uint8 else str(arr))
    except (ValueError, UnicodeDecodeError):
        return None


def _compact(blob: bytes, roots: list[str]):
    """(header as normalised data, payload) of a compact scene (8-byte magic, version, header length H,
    the JSON header space-padded, then the arrays)."""
    _, version, h = struct.unpack_from("<8sII", blob, 0)
    return version, _norm(json.loads(blob[16:16 + h].decode()), roots), blob[16 + h:]


def _b64(p: Path) -> bytes:
    """The compact scene a viewer's scene.js embeds (``window.ANIGS_SCENE_B64 = "..."``)."""
    text = p.read_text()
    return base64.b64decode(text[text.index('"') + 1:text.rindex('"')])


def same_content(a: Path, b: Path, roots: list[str]) -> bool:
    """Equal once paths and timings are normalised (json, npz, pt); False for other kinds."""
    if a.suffix == ".json":
        return _norm(json.loads(a.read_text()), roots) == _norm(json.loads(b.read_text()), roots)
    if a.suffix == ".npz":
        za, zb = np.load(a, allow_pickle=False), np.load(b, allow_pickle=False)
        if set(za.files) != set(zb.files):
            return False
        for k in za.files:
            x, y = za[k], zb[k]
            jx, jy = (_json_of(x), _json_of(y)) if x.dtype.kind in "US" or x.dtype == np.uint8 else (None, None)
            if jx is not None and jy is not None:
                if _norm(jx, roots) != _norm(jy, roots):
                    return False
            elif x.shape != y.shape or x.dtype != y.dtype or x.tobytes() != y.tobytes():
                return False
        return True
    if a.suffix == ".anigs":
        return _compact(a.read_bytes(), roots) == _compact(b.read_bytes(), roots)
    if a.name == "scene.js":
        return _compact(_b64(a), roots) == _compact(_b64(b), roots)
    if a.suffix == ".pt":
        import torch

        def eq(u, v) -> bool:
            if isinstance(u, torch.Tensor):
                return isinstance(v, torch.Tensor) and u.dtype == v.dtype and u.shape == v.shape and torch.equal(u, v)
            if isinstance(u, dict):
                return isinstance(v, dict) and set(u) == set(v) and all(eq(u[k], v[k]) for k in u)
            if isinstance(u, (list, tuple)):
                return isinstance(v, (list, tuple)) and len(u) == len(v) and all(eq(p, q) for p, q in zip(u, v))
            return _norm(u, roots) == _norm(v, roots)

        return eq(torch.load(a, weights_only=False), torch.load(b, weights_only=False))
    return False


def files(root: Path) -> dict[str, Path]:
    return {p.relative_to(root).as_posix(): p for p in root.rglob("*")
            if p.is_file() and not SKIP_DIRS & set(p.relative_to(root).parts)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("roots", nargs="*", help="results roots of the two runs (normalised in strings)")
    args = ap.parse_args()
    fa, fb = files(args.before), files(args.after)
    digest = lambda p: hashlib.sha256(p.read_bytes()).hexdigest()  # noqa: E731
    identical, content, differ = 0, 0, []
    for k in sorted(set(fa) & set(fb)):
        if digest(fa[k]) == digest(fb[k]):
            identical += 1
        elif same_content(fa[k], fb[k], [r.rstrip("/") for r in args.roots]):
            content += 1
        else:
            differ.append(k)
    print(f"byte-identical {identical}, same content (paths, timings normalised) {content}, different {len(differ)}")
    for k in differ:
        print("  different:", k)
    for k in sorted(set(fa) - set(fb)):
        print("  only before:", k)
    for k in sorted(set(fb) - set(fa)):
        print("  only after:", k)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
