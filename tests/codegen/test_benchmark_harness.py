"""benchmarks/dynamics_speed.py end to end on a few states (compiles Pinocchio: slow, not run by CI)."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
REQUIRED = ("id_speedup_vs_pinocchio", "fd_speedup_vs_pinocchio", "regressor_speedup_vs_pinocchio",
            "id_speedup_vs_casadi_rnea", "fd_speedup_vs_casadi_rnea")


@pytest.mark.slow
@pytest.mark.needs_cc
def test_benchmark_reports_required_keys_and_agrees_with_pinocchio():
    if shutil.which("c++") is None or not Path("/usr/include/eigen3/Eigen/Core").exists():
        pytest.skip("needs a C++ compiler and Eigen")
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "dynamics_speed.py"), "--robots", "denso",
                          "--samples", "2000", "--repeats", "1", "--json"], capture_output=True, text=True,
                         timeout=1200)
    assert run.returncode in (0, 1), run.stderr
    report = json.loads(run.stdout.strip().splitlines()[-1])
    denso = report["robots"]["denso"]
    for key in REQUIRED:
        assert denso[key] is None or denso[key] > 0
    # the harness checks every implementation against Pinocchio on the same states
    for key, error in denso["max_abs_error"].items():
        assert error < 1e-9, key
