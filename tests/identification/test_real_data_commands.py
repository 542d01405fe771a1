"""The command-line route docs/results/real-data.md prints for the shared TX40 (cut its one recording at 70 %, then
identify and diagnose --apply on default settings) runs as printed and gives the numbers the page states."""

from __future__ import annotations

import json
import os
import re

import pytest

from psdm_casadi.cli import main
from tests.conftest import DATASETS, ROOT

PAGE = ROOT / "docs" / "results" / "real-data.md"
TX40_IDENTIFY = [1.708, 4.745, 0.9164, 0.6363, 4.715, 1.53]  # the page's table
TX40_APPLIED = [1.711, 4.761, 0.9221, 0.6349, 1.813, 1.158]


def _cut_as_the_page_says(tmp_path):
    """Run the page's Python block in ``tmp_path`` with ../shared at this checkout's data root."""
    block = re.search(r"## The same from the command line.*?```python\n(.*?)```", PAGE.read_text(), re.S).group(1)
    here = os.getcwd()
    try:
        os.chdir(tmp_path)
        exec(block.replace("../shared/datasets/", f"{DATASETS}/"), {})  # noqa: S102 - the page's own code
    finally:
        os.chdir(here)


@pytest.mark.slow  # two consistent fits and a diagnosis of the TX40: about 30 s
@pytest.mark.real_data
def test_the_pages_tx40_commands_run_as_printed_and_give_its_numbers(tmp_path, capsys):
    if not (DATASETS / "staubli_tx40_figaroh").exists():
        pytest.skip("../shared/datasets/staubli_tx40_figaroh is absent")
    _cut_as_the_page_says(tmp_path)
    train, valid = tmp_path / "tx40_train", tmp_path / "tx40_valid"
    robot, model, applied = str(ROOT / "examples" / "staubli_tx40.toml"), tmp_path / "tx40.json", tmp_path / "b.json"
    assert main(["identify", robot, "--data", str(train), "--validate", str(valid), "--out", str(model)]) == 0
    first = json.loads(model.read_text())["validation"]["recordings"][0]["rmse"]
    assert first == pytest.approx(TX40_IDENTIFY, rel=2e-3)
    capsys.readouterr()
    argv = ["diagnose", str(model), "--train", str(train), "--validate", str(valid), "--apply", str(applied)]
    assert main(argv) == 0
    table = capsys.readouterr().out.split("validation RMSE after [N m] |")[1].splitlines()[0]
    assert [float(v) for v in table.strip(" |").split("|")] == pytest.approx(TX40_APPLIED, rel=2e-3)
