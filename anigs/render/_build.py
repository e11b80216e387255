"""Build and load the CPU compositing kernel (``csrc/raster.cpp``).

The kernel is plain C++ with a C ABI: no torch headers, so it compiles in seconds with
the system compiler (``$CXX``, else ``c++``/``g++``/``clang++``) and loads with ctypes.
The shared library is cached under ``$ANIGS_CACHE`` (default ``~/.cache/anigs``), keyed by
a hash of the source and flags, and written atomically so parallel jobs can race safely.
``anigs build-kernel`` builds it ahead of time (the README's set-up does this).
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
from pathlib import Path

SRC = Path(__file__).with_name("csrc") / "raster.cpp"
ABI_VERSION = 3
_FLAGS = ["-O3", "-std=c++17", "-shared", "-fPIC", "-ffp-contract=off", "-fno-math-errno"]
_LIB: ctypes.CDLL | None = None


class KernelBuildError(RuntimeError):
    pass


def cache_dir() -> Path:
    return Path(os.environ.get("ANIGS_CACHE", Path.home() / ".cache" / "anigs")) / "kernels"


def _compiler() -> str:
    for cand in [os.environ.get("CXX"), "c++", "g++", "clang++"]:
        if cand and shutil.which(cand):
            return cand
    raise KernelBuildError(
        "no C++ compiler found for the cpu rasterizer (set $CXX, or install g++: "
        "'apt-get install g++'); meanwhile backend='torch' works without one")


def library_path() -> Path:
    srcs = b"".join(p.read_bytes() for p in sorted(SRC.parent.glob("*.cpp")))
    key = hashlib.sha256(srcs + " ".join(_FLAGS).encode() + platform.machine().encode()).hexdigest()[:16]
    return cache_dir() / f"anigs_raster_{key}.so"


def build(verbose: bool = False) -> Path:
    """Compile the kernel if it is not cached; return the library path."""
    out = library_path()
    if out.exists():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    cxx = _compiler()
    fd, tmp = tempfile.mkstemp(prefix=".build.", suffix=".so", dir=out.parent)
    os.close(fd)
    errors = []
    try:
        for omp in (["-fopenmp"], []):  # fall back to single-threaded if OpenMP is missing
            cmd = [cxx, *_FLAGS, *omp, str(SRC), "-o", tmp]
            res = subprocess.run(cmd, capture_output=True, text=True)
            if res.returncode == 0:
                if verbose:
                    print(" ".join(cmd))
                os.replace(tmp, out)
                return out
            errors.append(f"$ {' '.join(cmd)}\n{res.stderr[-2000:]}")
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    raise KernelBuildError("building the cpu rasterizer failed:\n" + "\n".join(errors))


def load() -> ctypes.CDLL:
    """Load (building first if needed) the kernel library, with typed signatures."""
    global _LIB
    if _LIB is not None:
        return _LIB
    # Our OpenMP runtime is separate from torch's: idle threads must sleep, not spin, or the
    # two pools (and parallel Snakemake jobs) starve each other on small machines.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    lib = ctypes.CDLL(str(build()))
    if lib.anigs_abi_version() != ABI_VERSION:
        raise KernelBuildError(f"stale kernel library {library_path()}: delete it and retry")
    P, I = ctypes.c_void_p, ctypes.c_int
    lib.anigs_tile_counts.argtypes = [I, P, I, I, P]
    lib.anigs_bin.argtypes = [I, P, I, I, P, P, P, P]
    lib.anigs_forward.argtypes = [I, I, I, I, P, P, P, P, P, P, P, P, P, P, I]
    lib.anigs_backward.argtypes = [I, I, I, I, P, P, P, P, P, P, P, P, P, P, P, P, I]
    lib.anigs_reduce.argtypes = [I, I, P, P, P, P, P, I]
    lib.anigs_project_forward.argtypes = [I, P, I, I, P, P, P, P, P, P, P, P, P, P, I]
    lib.anigs_project_backward.argtypes = [I, P, I, I, P, P, P, P, P, P, P, P, P, P, I]
    for f in (lib.anigs_tile_counts, lib.anigs_bin, lib.anigs_forward, lib.anigs_backward, lib.anigs_reduce,
              lib.anigs_project_forward, lib.anigs_project_backward):
        f.restype = None
    _LIB = lib
    return lib


def available() -> bool:
    try:
        load()
        return True
    except KernelBuildError:
        return False
