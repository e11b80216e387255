"""No code picks a CUDA device by itself: anigs/device.py resolves the config's ``device``
(``auto`` | ``cpu`` | ``cuda`` | ``cuda:N``) and everything else uses what it returns. Checks on a
device's type (``dev.type == "cuda"``) are fine; choosing one (``torch.device("cuda")``,
``.cuda()``, ``.to("cuda")``, ``device="cuda:0"``) is not."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ALLOWED = {"anigs/device.py"}
# a device chosen in code: torch.device("cuda..."), .cuda(), .to("cuda..."), device="cuda...", map_location="cuda..."
PICKS = re.compile(r"""(torch\.device\(\s*["']cuda|\.cuda\(\s*\)|\.to\(\s*["']cuda|"""
                   r"""\b(device|map_location)\s*=\s*["']cuda)""")


def hard_coded(text: str) -> list[str]:
    """Lines of ``text`` that choose a CUDA device (comments ignored)."""
    out = []
    for line in text.splitlines():
        code = line.split("#", 1)[0]
        if PICKS.search(code):
            out.append(line.strip())
    return out


def test_the_check_finds_a_hard_coded_device():
    bad = 'x = x.cuda()\ny = torch.device("cuda")\nz = t.to("cuda:0")\nf(device="cuda")\n'
    assert len(hard_coded(bad)) == 4
    good = 'if dev.type == "cuda":\n    pass\nd = get_device(cfg.device)  # not torch.device("cuda")\n' \
           'ok = str(config["device"]).startswith("cuda")\n'
    assert hard_coded(good) == []


def test_no_code_outside_device_py_picks_cuda():
    files = [p for d in ("anigs", "workflow", "benchmarks") for p in (ROOT / d).rglob("*")
             if p.suffix in (".py", ".smk", ".sh") and p.is_file()] + [ROOT / "Snakefile"]
    assert len(files) > 50
    found = {str(p.relative_to(ROOT)): hits for p in files
             if str(p.relative_to(ROOT)) not in ALLOWED and (hits := hard_coded(p.read_text(errors="replace")))}
    assert found == {}, f"a CUDA device chosen outside anigs/device.py (use anigs.device.get_device): {found}"
