"""benchmarks/publish_tables.py: the published tables are the generated Markdown, between markers."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "publish_tables.py"


def _run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True)


def test_blocks_are_filled_from_the_results_and_check_sees_staleness(tmp_path):
    doc = tmp_path / "README.md"
    doc.write_text("intro\n<!-- generated: tables -->\nold | figures\n<!-- end generated: tables -->\nmiddle\n"
                   "<!-- generated: tradeoff -->\n<!-- end generated: tradeoff -->\nend\n")
    (tmp_path / "results" / "tables").mkdir(parents=True)
    (tmp_path / "results" / "tables" / "table5_ablation.md").write_text("## Ablation\n\n| a | b |\n|---|---|\n| 1 | 2 |\n")
    (tmp_path / "results" / "tables" / "table1_fvd.md").write_text("## FVD\n\n| x |\n|---|\n| 3 |\n")
    assert _run("--results", tmp_path / "results", "--into", doc, "--check").returncode == 1  # stale
    res = _run("--results", tmp_path / "results", "--into", doc)
    assert res.returncode == 0, res.stderr
    text = doc.read_text()
    assert "old | figures" not in text and "| 1 | 2 |" in text and "#### Ablation" in text
    assert text.index("#### FVD") < text.index("#### Ablation")  # the paper's order
    assert text.startswith("intro\n") and "\nmiddle\n" in text and text.endswith("end\n")
    assert "`results/tables/table1_fvd.md`" in text and str(tmp_path) not in text
    assert "no reports" in res.stdout  # the tradeoff block is left as it was
    assert _run("--results", tmp_path / "results", "--into", doc, "--check").returncode == 0


def test_missing_markers_are_an_error(tmp_path):
    doc = tmp_path / "README.md"
    doc.write_text("no markers\n")
    (tmp_path / "results" / "tables").mkdir(parents=True)
    (tmp_path / "results" / "tables" / "weightfree.md").write_text("| a |\n")
    res = _run("--results", tmp_path / "results", "--into", doc)
    assert res.returncode != 0 and "markers" in res.stderr + res.stdout
    assert doc.read_text() == "no markers\n"
