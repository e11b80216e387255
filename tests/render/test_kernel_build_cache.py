"""Kernel build cache and fallback: only a kernel that cannot be built here falls back to torch (other
numerics); a cached library that does not load, or an OS error while building, fails loudly; a
fallback build (no -march / no OpenMP, other float bits) is never cached under the full-flag name."""
from __future__ import annotations

import errno
import subprocess

import pytest

from anigs.render import kernel as render_kernel
from anigs.ssim import kernel as ssim_kernel


@pytest.fixture
def fresh(monkeypatch, tmp_path):
    """An empty kernel cache and no loaded libraries (both restored afterwards)."""
    monkeypatch.setenv("ANIGS_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(render_kernel, "_LIB", None)
    monkeypatch.setattr(ssim_kernel, "_LIB", None)
    monkeypatch.setattr(ssim_kernel, "_FAILED", None)
    return tmp_path


def _garbage(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"not a shared library\x00" * 64)
    return path


def test_ssim_library_that_does_not_load_raises_not_falls_back(fresh):
    path = _garbage(ssim_kernel.library_path())
    with pytest.raises(render_kernel.KernelLoadError, match=rf"(?s){path.name}.*delete .* and rerun"):
        ssim_kernel.available()
    assert ssim_kernel.failure() is None


def test_raster_library_that_does_not_load_raises_not_falls_back(fresh):
    path = _garbage(render_kernel.library_path())
    with pytest.raises(render_kernel.KernelLoadError, match=rf"(?s){path.name}.*delete .* and rerun"):
        render_kernel.available()


def test_os_error_launching_the_compiler_raises_not_falls_back(fresh, monkeypatch):
    def no_memory(cmd, **kw):
        raise OSError(errno.ENOMEM, "Cannot allocate memory")

    monkeypatch.setattr(render_kernel.subprocess, "run", no_memory)
    with pytest.raises(render_kernel.KernelLoadError, match="Cannot allocate memory.*rerun"):
        ssim_kernel.available()
    with pytest.raises(render_kernel.KernelLoadError, match="Cannot allocate memory.*rerun"):
        render_kernel.available()
    assert ssim_kernel.failure() is None


def test_no_compiler_still_falls_back(fresh, monkeypatch):
    monkeypatch.setattr(render_kernel.shutil, "which", lambda name: None)
    assert not ssim_kernel.available()
    assert "no C++ compiler found" in ssim_kernel.failure()
    assert not render_kernel.available()


@pytest.fixture
def tiny_src(tmp_path, monkeypatch):
    """A one-function C++ file, built with the -march level of this CPU (``native``)."""
    monkeypatch.setenv("ANIGS_KERNEL_ARCH", "native")
    monkeypatch.delenv("ANIGS_KERNEL_THREADS", raising=False)
    src = tmp_path / "tiny.cpp"
    src.write_text('extern "C" int tiny_answer() { return 42; }\n')
    return src


def test_fallback_build_is_not_cached_under_the_full_flag_key(tiny_src, tmp_path, monkeypatch, caplog):
    render_kernel._compiler()  # skips nothing: no compiler here fails this test, as the kernels need one
    out = tmp_path / "cache" / "tiny_full.so"
    real_run = subprocess.run
    ran: list[list[str]] = []

    def march_killed(cmd, **kw):
        ran.append(cmd)
        if any(c.startswith("-march") for c in cmd):
            return subprocess.CompletedProcess(cmd, 1, "", "c++: fatal error: Killed signal terminated program cc1plus")
        return real_run(cmd, **kw)

    monkeypatch.setattr(render_kernel.subprocess, "run", march_killed)
    got = render_kernel.compile_cached(tiny_src, out, "the tiny kernel")
    assert not out.exists()
    assert got != out and got.exists() and "no-march" in got.name
    assert "-march=native" in ran[0] and not any(c.startswith("-march") for c in ran[-1])
    assert "-fopenmp" in ran[-1] and "no-openmp" not in got.name
    assert render_kernel.open_library(got, "the tiny kernel").tiny_answer() == 42
    assert "full-flag build failed" in caplog.text and got.name in caplog.text

    # the full flags fail again: the cached fallback is reused (its flags logged), not rebuilt
    ran.clear()
    assert render_kernel.compile_cached(tiny_src, out, "the tiny kernel") == got
    assert ran and all("-march=native" in cmd for cmd in ran)  # only the -march variants are tried again

    # a later run with a working compiler builds the full-flag library under the full-flag key
    ran.clear()
    monkeypatch.setattr(render_kernel.subprocess, "run", lambda cmd, **kw: (ran.append(cmd), real_run(cmd, **kw))[1])
    assert render_kernel.compile_cached(tiny_src, out, "the tiny kernel") == out
    assert out.exists() and len(ran) == 1 and "-march=native" in ran[0] and "-fopenmp" in ran[0]
    assert render_kernel.compile_cached(tiny_src, out, "the tiny kernel") == out and len(ran) == 1
