"""anigs CMD ... --then CMD ...: commands run one after another in one process."""
import json
import logging

import pytest

from anigs.cli import _split_chain, main


def test_split_chain_gives_each_command_the_global_options():
    assert _split_chain(["--threads", "2", "export", "--out", "a"]) == [["--threads", "2", "export", "--out", "a"]]
    parts = _split_chain(["-v", "--threads", "2", "round", "--x", "1", "--then", "update", "--y", "2"])
    assert parts == [["-v", "--threads", "2", "round", "--x", "1"], ["-v", "--threads", "2", "update", "--y", "2"]]
    for bad in (["export", "--then"], ["export", "--then", "--out", "x"], ["--then", "export"]):
        with pytest.raises(SystemExit, match="--then must separate commands"):
            _split_chain(bad)


def test_chain_runs_in_order_and_stops_at_the_first_failure(tmp_path, caplog):
    """Two `tables` commands chained: both write; a failing first command stops the chain."""
    caplog.set_level(logging.INFO)
    rec = {"schema": "anigs-metrics/1", "scene": "s", "method": "Ours", "metrics": {}}
    (tmp_path / "m.json").write_text(json.dumps(rec))
    ok = ["tables", "--metrics", str(tmp_path / "m.json")]
    assert main([*ok, "--out", str(tmp_path / "a"), "--then", *ok, "--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "a" / "tables.json").is_file() and (tmp_path / "b" / "tables.json").is_file()
    assert "chain: command 2 of 2 (tables)" in caplog.text
    bad = ["tables", "--metrics", str(tmp_path / "missing.json"), "--out", str(tmp_path / "c")]
    assert main([*bad, "--then", *ok, "--out", str(tmp_path / "d")]) == 1
    assert not (tmp_path / "d").exists()
