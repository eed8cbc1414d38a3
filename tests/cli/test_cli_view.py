"""``qpik view``'s errors: one line and exit code 2 for a taken port, a missing viser, a missing browser, a bad
file; ``import qpik`` does not import viser."""

from __future__ import annotations

import socket
import subprocess
import sys

import pytest

from qpik.cli import main


def _one_line(capsys) -> str:
    """The one line of stderr besides the compiler's progress lines (a cold compile cache prints them first)."""
    err = "".join(line for line in capsys.readouterr().err.splitlines(True) if not line.startswith("qpik: compil"))
    assert err.count("\n") == 1, err
    return err.strip()


def test_import_qpik_leaves_viser_alone():
    code = "import sys, qpik; qpik.view; assert 'viser' not in sys.modules and 'trimesh' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_without_viser_one_line(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "viser", None)  # import viser raises ImportError
    monkeypatch.delitem(sys.modules, "qpik.viewer.server", raising=False)
    assert main(["view", "iiwa14"]) == 2
    assert _one_line(capsys) == "qpik view: viser is not installed: pip install 'qpik[view]'"


def test_taken_port_one_line(capsys):
    pytest.importorskip("viser", reason="viser is not installed (pip install 'qpik[view]')")
    with socket.socket() as other:
        other.bind(("127.0.0.1", 0))
        other.listen()
        port = other.getsockname()[1]
        assert main(["view", "iiwa14", "--port", str(port)]) == 2
    line = _one_line(capsys)
    assert line.startswith("qpik view: port ") and str(port) in line


def test_screenshot_without_browser_one_line(monkeypatch, capsys, tmp_path):
    pytest.importorskip("viser", reason="viser is not installed (pip install 'qpik[view]')")
    monkeypatch.setenv("QPIK_BROWSER", str(tmp_path / "no-such-browser"))
    assert main(["view", "panda", "--port", "0", "--screenshot", str(tmp_path / "x.png")]) == 2
    assert _one_line(capsys).startswith("qpik view: no headless browser")
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--screenshot", "x.jpg"], "must end in .png"),
        (["--objective", "speed"], "objective: expected one of"),
        (["--port", "70000"], "port: expected an integer in 0..65535"),
        (["--play", "nothing.csv"], "expected the .npz plan file"),
        (["--robot", "panda"], "given twice"),
    ],
)
def test_bad_arguments_one_line(argv, message, capsys):
    pytest.importorskip("viser", reason="viser is not installed (pip install 'qpik[view]')")
    assert main(["view", "iiwa14", *argv]) == 2
    assert message in _one_line(capsys)
