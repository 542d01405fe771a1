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
        [sys.executable, str(SCRIPT), "--robots", "denso", "--steps", "3", "--horizon", "4", "--no-jit", "--json"],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=ROOT,
    )
    assert run.returncode in (0, 1), run.stderr
    denso = json.loads(run.stdout)["robots"]["denso"]
    for key in ("rate_hz", "mean_step_ms", "max_step_ms", "tracking_rmse", "solver"):
        assert key in denso
    peers = {"casadi_rnea", "casadi_rnea_id_derivatives", "pinocchio_casadi", "pinocchio_callback"}
    assert set(denso["peers"]) == peers
    assert set(denso["variants"]) == {"psdm_ad", "psdm_external"}
    rows = [denso, *denso["variants"].values()] + [p for p in denso["peers"].values() if not p.get("error")]
    for row in rows:
        assert row["tracking_rmse"] < 1e-3 and row["limit_violation"] == 0.0
        assert row["max_step_ms"] >= row["mean_step_ms"] > 0
    if denso["peers"]["pinocchio_casadi"].get("error"):
        assert "pinocchio.casadi" in denso["peers"]["pinocchio_casadi"]["error"]
