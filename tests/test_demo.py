"""qpik.demo: the first run says that it compiles, later runs do not (the sections themselves run in CI's part 1)."""

from __future__ import annotations

import pytest

from qpik.compiled import compiler
from qpik.demo import run_all


@pytest.mark.skipif(compiler() is None, reason="no C compiler: nothing is compiled")
def test_the_first_run_says_it_compiles(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path / "cache"))
    run_all(tmp_path / "out", only=["no such section"])
    assert "first run: qpik compiles" in capsys.readouterr().out
    (tmp_path / "cache").mkdir()
    (tmp_path / "cache" / "fk_iiwa14.so").write_bytes(b"")
    run_all(tmp_path / "out", only=["no such section"])
    assert "first run" not in capsys.readouterr().out
