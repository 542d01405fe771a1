"""The command-line route docs/results/real-data.md prints for the shared TX40 (its one recording, the last 30 % held
out with ``--holdout 0.3``, then identify and diagnose --apply on default settings) runs as printed and gives the
numbers the page states."""

from __future__ import annotations

import json
import re
import shlex

import pytest

from psdm_casadi.cli import main
from tests.conftest import DATASETS, ROOT

PAGE = ROOT / "docs" / "results" / "real-data.md"
TX40_IDENTIFY = [1.711, 4.764, 0.9211, 0.6351, 1.812, 1.158]  # the page's table: the file's coupling fitted
TX40_APPLIED = TX40_IDENTIFY  # the page's table: nothing to apply, so no refit: the model file as it is


def _page_command(start: str, tmp_path) -> list:
    """The page's command line that begins with ``start`` (its comment dropped), as ``main``'s argv: ../shared at this
    checkout's data root, examples/ in this checkout, the outputs in ``tmp_path``."""
    block = re.search(r"## The same from the command line.*?```\n(psdm .*?)```", PAGE.read_text(), re.S).group(1)
    (line,) = [line for line in block.splitlines() if line.startswith(start)]
    argv = shlex.split(line.split("#")[0])[1:]
    out = []
    for word in argv:
        if word.startswith("../shared/datasets/"):
            word = str(DATASETS / word.removeprefix("../shared/datasets/"))
        elif word.startswith("examples/"):
            word = str(ROOT / word)
        elif word.endswith(".json"):
            word = str(tmp_path / word)
        out.append(word)
    return out


@pytest.mark.slow  # a consistent fit and a diagnosis with its refit of the TX40: about 25 s
@pytest.mark.real_data
def test_the_pages_tx40_commands_run_as_printed_and_give_its_numbers(tmp_path, capsys):
    if not (DATASETS / "staubli_tx40_figaroh").exists():
        pytest.skip("../shared/datasets/staubli_tx40_figaroh is absent")
    identify = _page_command("psdm identify examples/staubli_tx40.toml", tmp_path)
    assert "--holdout" in identify and "--validate" not in identify  # one recording, its last part held out
    assert main(identify) == 0
    document = json.loads((tmp_path / "tx40.json").read_text())
    first = document["validation"]["recordings"][0]["rmse"]
    assert first == pytest.approx(TX40_IDENTIFY, rel=2e-3)
    assert document["identification"]["holdout"]["recordings"][0]["cut_sample"] == 31499  # int(0.7 * 45000)
    capsys.readouterr()
    diagnose = _page_command("psdm diagnose tx40.json", tmp_path)
    assert "--validate" not in diagnose  # the model's held-out part
    assert main(diagnose) == 0
    captured = capsys.readouterr()
    text = captured.out
    rows = text.split("## Validation per joint")[1].split("\n\n")[1].splitlines()[2:]  # | joint | before | after |...
    assert [float(row.split("|")[3]) for row in rows] == pytest.approx(TX40_APPLIED, rel=2e-3)
    assert "Held out: training: the first 31499 samples of" in text
    # identify fitted the robot file's coupling (``coupled_drives``): the diagnosis carries it at the file's size and
    # adds nothing, so --apply runs no refit and writes no file (the table's "after" is the model file as it is)
    assert {"coupling[j6->j5]", "coupling[j5->j6]"} <= {e["label"] for e in document["findings"]}
    assert "nothing to apply" in captured.err and "tx40_2.json' was not written" in captured.err
    assert not (tmp_path / "tx40_2.json").exists()
