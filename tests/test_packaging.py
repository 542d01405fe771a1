"""The installed package works without the checkout: a wheel in a fresh venv runs ``psdm demo --quick``.

The venv gets the wheel alone (``--no-deps``); its third-party dependencies come from the
environment running the tests through a ``.pth`` file that adds that site-packages folder and
repeats its ``.pth`` lines except the editable install's, so the checkout stays out.
The demo runs from an empty folder, so nothing can be read from the checkout by a relative path.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(command, cwd, timeout=600):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 0, f"{command} failed ({result.returncode}):\n{result.stdout}\n{result.stderr}"
    return result


def _dependency_lines() -> str:
    """A .pth text that puts the test environment's dependencies on sys.path, without its editable install."""
    purelib = Path(sysconfig.get_paths()["purelib"])
    lines = [str(purelib)]
    for pth in sorted(purelib.glob("*.pth")):
        if "editable" not in pth.name:  # e.g. cmeel.pth, which adds Pinocchio's prefix
            lines += pth.read_text().splitlines()
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A fresh venv with the project's wheel installed, and an empty working folder."""
    base = tmp_path_factory.mktemp("wheel")
    # build from a copy: setuptools keeps a build/ folder whose stale modules would ship in the wheel
    source = base / "source"
    shutil.copytree(
        ROOT,
        source,
        ignore=shutil.ignore_patterns(
            ".git", ".venv", "build", "*.egg-info", "__pycache__", ".pytest_cache", ".ruff_cache", "demo_report"
        ),
    )
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(base / "dist"), str(source)], base)
    wheels = sorted((base / "dist").glob("psdm_casadi-*.whl"))
    assert len(wheels) == 1
    venv.EnvBuilder(with_pip=False).create(base / "venv")
    python = base / "venv" / "bin" / "python"
    site = Path(
        _run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], base).stdout.strip()
    )
    (site / "test_dependencies.pth").write_text(_dependency_lines())
    _run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "--quiet", str(wheels[0])], base
    )
    work = base / "empty"
    work.mkdir()
    return python, work


def test_the_wheel_carries_the_robots_and_templates_and_not_the_checkout(installed):
    python, work = installed
    probe = (
        "import json, psdm_casadi, codegen, psdm_casadi.robot as r;"
        "print(json.dumps({'package': psdm_casadi.__file__, 'robots': r.builtin_robot_names(),"
        "'template': (__import__('pathlib').Path(codegen.__file__).parent / 'templates').is_dir(),"
        "'peer_template': __import__('codegen.peers.speed', fromlist=['TEMPLATE']).TEMPLATE.is_file()}))"
    )
    found = json.loads(_run([str(python), "-c", probe], work).stdout)
    assert not Path(found["package"]).resolve().is_relative_to(ROOT)
    assert {"denso_vs6556g", "scara"} <= set(found["robots"])
    assert found["template"] and found["peer_template"]


@pytest.mark.slow
@pytest.mark.needs_cc
def test_installed_psdm_runs_the_quick_demo_from_an_empty_folder(installed):
    python, work = installed
    psdm = python.parent / "psdm"
    derive = json.loads(_run([str(psdm), "derive", "denso_vs6556g", "--json"], work).stdout)
    assert (derive["p"], derive["l"]) == (1318, 32)
    _run([str(psdm), "--quiet", "demo", "--quick", "--out", "report"], work)
    summary = json.loads((work / "report" / "summary.json").read_text())
    assert any(f["effect"] == "spring" and f["joints"] == [4] for f in summary["diagnosis"]["findings"])
    assert (work / "report" / "report.md").stat().st_size > 0
    # the loop closed: recalibrated with the spring, consistent, Kt within 1 % of the virtual truth, better fit
    assert summary["final_model_consistent"] is True
    assert max(summary["recalibration"]["kt_rel_err"]) < 0.01
    assert summary["final_min_r2_all"] > summary["identification"]["r2_min_all"]
