"""``anigs build-kernel``: compile the CPU kernels now, the rasterizer and the fused SSIM (the set-up
script calls this; otherwise each builds on first use)."""
from __future__ import annotations

import argparse

from anigs.render import kernel as render_kernel
from anigs.ssim import kernel as ssim_kernel


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quiet", action="store_true")


def main(args: argparse.Namespace) -> int:
    path = render_kernel.build(verbose=not args.quiet)
    render_kernel.load()
    ssim = ssim_kernel.build(verbose=not args.quiet)
    ssim_kernel.load()
    if not args.quiet:
        print(f"cpu rasterizer ready: {path}\nfused SSIM kernel ready: {ssim}")
    return 0
