"""Build and load the CPU rasterizer kernel (``csrc/raster.cpp``, which includes the other files).

The kernel is plain C++17 with OpenMP (or, without it, its own std::thread pool) and a C
ABI: no torch headers, so it compiles in seconds with
the system compiler (``$CXX``, else ``c++``/``g++``/``clang++``) and loads with ctypes.
The shared library is cached under ``$ANIGS_CACHE`` (default ``~/.cache/anigs``), keyed by
a hash of the source and flags, and written atomically so parallel jobs can race safely.
``anigs build-kernel`` builds it ahead of time (the README's set-up does this).

On x86-64 Linux the kernel targets the best instruction-set level the CPU reports
(x86-64-v4 = AVX-512, v3 = AVX2, else the baseline). The level is part of the cache key,
so machines sharing a home directory each get a library their CPU can run;
``ANIGS_KERNEL_ARCH`` overrides the choice (e.g. ``x86-64-v3``; ``none`` for the baseline).

A build without the ``-march`` level or OpenMP computes other float bits, so it is never cached
under the full-flag name: it gets its own name (``<name>.no-march.so`` ...), a warning names it,
and every later run tries the full-flag build again first. Falling back to the torch paths is
only for a kernel that cannot be built here (:class:`KernelBuildError`); a library that exists
but does not load, or an OS error while building, raises :class:`KernelLoadError` so the job
fails (and is rerun) instead of silently training with other numerics.
"""
from __future__ import annotations

import ctypes
import hashlib
import logging
import os
import platform
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path

SRC = Path(__file__).with_name("csrc") / "raster.cpp"
ABI_VERSION = 5
FLAGS = ["-O3", "-std=c++17", "-shared", "-fPIC", "-pthread", "-ffp-contract=off", "-fno-math-errno"]
_LIB: ctypes.CDLL | None = None
log = logging.getLogger("anigs.kernel")

# x86-64 micro-architecture levels and the /proc/cpuinfo flags each needs.
_X86_LEVELS = [
    ("x86-64-v4", {"avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"}),
    ("x86-64-v3", {"avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "movbe", "xsave"}),
]


class KernelBuildError(RuntimeError):
    """The kernel cannot be built on this machine (no compiler, every flag variant rejected):
    callers fall back to their torch path."""


class KernelLoadError(RuntimeError):
    """The kernel builds here but this attempt failed (a cached library that does not load, an OS
    error while building): never a reason to fall back, since the fallback has other numerics."""


def cache_dir() -> Path:
    return Path(os.environ.get("ANIGS_CACHE", Path.home() / ".cache" / "anigs")) / "kernels"


def _compiler() -> str:
    for cand in [os.environ.get("CXX"), "c++", "g++", "clang++"]:
        if cand and shutil.which(cand):
            return cand
    raise KernelBuildError(
        "no C++ compiler found for the cpu rasterizer (set $CXX, or install g++: "
        "'apt-get install g++'); meanwhile backend='torch' works without one")


def arch_flags() -> list[str]:
    """``-march`` level for this CPU (x86-64 Linux only; empty elsewhere or when unsure)."""
    env = os.environ.get("ANIGS_KERNEL_ARCH")
    if env is not None:
        return [] if env in ("", "none") else [f"-march={env}"]
    if platform.machine() not in ("x86_64", "AMD64"):
        return []
    try:
        with open("/proc/cpuinfo") as fh:
            flags = next((set(line.split(":", 1)[1].split()) for line in fh if line.startswith("flags")), set())
    except OSError:
        return []
    for level, need in _X86_LEVELS:
        if need <= flags:
            return [f"-march={level}"]
    return []


def thread_flags() -> list[str]:
    """OpenMP by default; ``ANIGS_KERNEL_THREADS=pool`` builds the kernel's own thread pool.

    With OpenMP the kernel's loops run on torch's own OpenMP threads (pip torch ships
    libgomp.so.1 and the loader shares it), so no extra threads compete with torch's, which
    spin for a while after every torch op. The pool (``csrc/pool.cpp``, also the fallback
    when the compiler has no OpenMP) never waits for a worker that the OS has not scheduled,
    which helps on an overloaded machine; there, ``OMP_WAIT_POLICY=PASSIVE`` (set before
    importing torch) or one thread per job helps torch and the OpenMP kernel alike.
    """
    return [] if os.environ.get("ANIGS_KERNEL_THREADS") == "pool" else ["-fopenmp"]


def library_path() -> Path:
    srcs = b"".join(p.read_bytes() for p in sorted(SRC.parent.glob("*.cpp")))
    flags = " ".join(FLAGS + arch_flags() + thread_flags())
    key = hashlib.sha256(srcs + flags.encode() + platform.machine().encode()).hexdigest()[:16]
    return cache_dir() / f"anigs_raster_{key}.so"


def build(verbose: bool = False) -> Path:
    """Compile the kernel if it is not cached; return the library path."""
    return compile_cached(SRC, library_path(), "the cpu rasterizer", verbose)


def compile_cached(src: Path, out: Path, what: str, verbose: bool = False) -> Path:
    """Compile ``src`` into the shared library ``out`` (keyed by the full flags) unless it exists,
    atomically (a temporary name, then a rename, so parallel jobs never load a half-written file).

    If the full flags fail, builds without the ``-march`` level and/or OpenMP into a name of its
    own (:func:`_variant_path`; reused if cached) and warns: never under ``out``, so a later run
    retries the full flags. All variants failing raises :class:`KernelBuildError` naming ``what``;
    an OS error (cache folder, launching the compiler) raises :class:`KernelLoadError`."""
    if out.exists():
        return out
    cxx = _compiler()
    arch, omp = arch_flags(), thread_flags()
    # fall back to the kernel's own thread pool if OpenMP is missing, and to the baseline
    # instruction set if the compiler does not know the -march level
    variants = [(m, o) for m in ([arch, []] if arch else [[]]) for o in ([omp, []] if omp else [[]])]
    errors = []
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        for march, o in variants:
            flags = [*FLAGS, *march, *o]
            target = _variant_path(out, [*(arch if not march else []), *(omp if not o else [])])
            if target != out and target.exists():
                return _warn_fallback(target, what, flags, errors)
            err = _compile(cxx, flags, src, target, verbose)
            if err is None:
                return target if target == out else _warn_fallback(target, what, flags, errors)
            errors.append(err)
    except OSError as exc:
        raise KernelLoadError(f"building {what} into {out} failed with an OS error ({exc}); the compiler is "
                              f"there, so this is not a reason to fall back: check that {out.parent} is "
                              "writable and memory is free, then rerun") from exc
    raise KernelBuildError(f"building {what} failed:\n" + "\n".join(errors))


def _variant_path(out: Path, dropped: list[str]) -> Path:
    """Where the build without the ``dropped`` flags is cached: ``out`` itself when none is dropped."""
    tags = sorted({"no-march" if f.startswith("-march") else "no-openmp" for f in dropped})
    return out.with_name(".".join([out.stem, *tags, "so"])) if tags else out


def _compile(cxx: str, flags: list[str], src: Path, target: Path, verbose: bool) -> str | None:
    """Compile ``src`` to ``target`` atomically; None on success, else the command and its errors."""
    fd, tmp = tempfile.mkstemp(prefix=".build.", suffix=".so", dir=target.parent)
    os.close(fd)
    try:
        cmd = [cxx, *flags, str(src), "-o", tmp]
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            return f"$ {' '.join(cmd)}\n{res.stderr[-2000:]}"
        if verbose:
            print(" ".join(cmd))
        os.replace(tmp, target)
        return None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _warn_fallback(path: Path, what: str, flags: list[str], errors: list[str]) -> Path:
    """Log that ``what`` runs a fallback build (``flags``: other float bits than the full flags)."""
    log.warning("%s: the full-flag build failed; using %s, built with '%s' (other float bits than "
                "the full flags); the next run tries the full flags again. First error:\n%s",
                what, path, " ".join(flags), errors[0] if errors else "?")
    return path


def open_library(path: Path, what: str) -> ctypes.CDLL:
    """``ctypes.CDLL(path)``; a library that exists but does not load raises :class:`KernelLoadError`."""
    try:
        return ctypes.CDLL(str(path))
    except OSError as exc:
        raise KernelLoadError(f"cannot load {what} from {path} ({exc}): the cached library is damaged or "
                              f"not for this machine; delete {path} and rerun (it is rebuilt)") from exc


def check_abi(lib: ctypes.CDLL, symbol: str, expected: int, path: Path) -> None:
    """Raise :class:`KernelLoadError` if the library's ABI version function does not return ``expected``."""
    if getattr(lib, symbol)() != expected:
        raise KernelLoadError(f"stale kernel library {path} (ABI is not {expected}): delete it and rerun")


def unavailable_reason(load: Callable[[], object]) -> str | None:
    """None if ``load()`` succeeds; why, if the kernel cannot be built here (:class:`KernelBuildError`,
    the only case a caller may fall back to torch). Every other error propagates."""
    try:
        load()
        return None
    except KernelBuildError as exc:
        return str(exc)


def load() -> ctypes.CDLL:
    """Load (building first if needed) the kernel library, with typed signatures."""
    global _LIB
    if _LIB is not None:
        return _LIB
    if thread_flags():
        # pip torch ships its own libgomp.so.1 and the loader shares it with the kernel (same
        # soname): the kernel's loops then run on torch's threads with torch's wait policy.
        # With a separate OpenMP runtime (another torch build), make ours passive so that the
        # two pools do not starve each other on small machines.
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    path = build()
    lib = open_library(path, "the cpu rasterizer")
    check_abi(lib, "anigs_abi_version", ABI_VERSION, path)
    P, I = ctypes.c_void_p, ctypes.c_int
    lib.anigs_preprocess.argtypes = [I, P, I, I, P, P, P, P, P, I, I, P, P, P, P, P, P, I, I]
    lib.anigs_preprocess.restype = I
    lib.anigs_preprocess_backward.argtypes = [I, P, I, I, P, P, P, P, I, I, P, P, P, P, P, P, P, P, I]
    lib.anigs_sort_count.argtypes = [I, P, P, P, P, P, P, I, I, P, P, ctypes.POINTER(ctypes.c_longlong), I]
    lib.anigs_sort_count.restype = I
    lib.anigs_composite_forward.argtypes = [I, I, I] + [P] * 19 + [I]
    lib.anigs_composite_backward.argtypes = [I, I, I, I] + [P] * 20 + [I]
    for f in (lib.anigs_preprocess_backward, lib.anigs_composite_forward, lib.anigs_composite_backward):
        f.restype = None
    _LIB = lib
    return lib


def available() -> bool:
    """Whether the kernel builds and loads here; False only if it cannot be built (see
    :func:`unavailable_reason`)."""
    return unavailable_reason(load) is None
