"""The PyClaw comparison: runs when PyClaw is installed (`make bench-peers`), and says how
to install it when it is not."""

import pytest

from ale_xfem import cli
from ale_xfem.studies import peers


def test_without_pyclaw_the_command_says_how_to_install_it(monkeypatch, capsys):
    monkeypatch.setattr(peers, "pyclaw_available", lambda: False)
    assert cli.main(["bench", "--peers"]) == cli.EXIT_BAD_INPUT
    assert "make bench-peers" in capsys.readouterr().err


def test_all_three_converge_on_sod_and_the_table_is_written(tmp_path):
    pytest.importorskip("clawpack.pyclaw")
    rows = peers.run_peer_comparison(tmp_path, sizes=(100, 200, 400), echo=lambda line: None)
    for method in {r["method"] for r in rows}:
        errors = [r["L1_density"] for r in sorted(rows, key=lambda r: r["cells"]) if r["method"] == method]
        assert errors[0] > errors[1] > errors[2], method
        assert errors[2] < 2.5e-3, method  # Sod at 400 cells, all three second-order-ish schemes
    assert (tmp_path / "peers.md").read_text().count("|") > 20 and (tmp_path / "peers.png").exists()
