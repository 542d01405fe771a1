"""benchmarks/mpc.py: its JSON keys and rows on a tiny run, and its argument errors."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "mpc.py"


def test_bad_step_count_exits_2_naming_the_flag():
    run = subprocess.run([sys.executable, str(SCRIPT), "--steps", "0"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2
    assert "--steps must be a positive integer" in run.stderr
    assert "Traceback" not in run.stderr


@pytest.mark.slow
@pytest.mark.needs_cc
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_json_has_every_row_and_the_rows_track_the_plant():
    run = subprocess.run(
        [sys.executable, str(SCRIPT), "--robots", "denso", "--steps", "3", "--horizon", "4", "--json"],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=ROOT,
    )
    assert run.returncode in (0, 1), run.stderr
    denso = json.loads(run.stdout)["robots"]["denso"]
    for key in ("rate_hz", "tracking_rmse", "limit_violation", "speedup_vs_crocoddyl", "load_average", "qp_solver"):
        assert key in denso
    assert set(denso["rows"]) == {"psdm_rti", "psdm_sqp"}
    assert "Panda only" in denso["skipped"]["crocoddyl"]
    for row in denso["rows"].values():
        assert row["tracking_rmse"] < 1e-3 and row["limit_violation"] == 0.0
        assert row["max_step_ms"] >= row["mean_step_ms"] > 0


def test_model_file_that_does_not_read_exits_2_naming_it(tmp_path):
    broken = tmp_path / "model.json"
    broken.write_text("{}")
    run = subprocess.run(
        [sys.executable, str(SCRIPT), "--robots", "denso", "--steps", "2", "--horizon", "2", "--model", str(broken)],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
    )  # fmt: skip
    assert run.returncode == 2, run.stderr
    assert "model.json" in run.stderr and "format must be" in run.stderr
    assert "Traceback" not in run.stderr
    run = subprocess.run([sys.executable, str(SCRIPT), "--model", str(broken)], capture_output=True, text=True)
    assert run.returncode == 2 and "--model needs one robot" in run.stderr
