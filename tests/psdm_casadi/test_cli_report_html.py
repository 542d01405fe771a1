"""``report.html`` of ``psdm identify`` and ``psdm diagnose``: written, self-contained, one plot per joint, a summary
first, and the numbers of the model file and of the diagnosis report (read back out of the page's plot JSON and
table cells); rendered by a real headless Chromium where one is installed."""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess

import numpy as np
import pytest

from identification.data.io import save_recording
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.cli.html_report import default_html_path, html_output
from tests.conftest import DENSO_FILE
from tests.psdm_casadi.html_page import assert_self_contained, plot_data, table_rows
from trajopt.experiments import sine_experiment

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def recordings(tmp_path_factory, denso):
    """A short training and validation pair of the virtual Denso with a hidden spring on joint 2."""
    folder = tmp_path_factory.mktemp("html_recordings")
    for k, (name, duration) in enumerate((("train.npz", 5.0), ("valid.npz", 3.0))):
        rng = np.random.default_rng(40 + k)
        reference = sine_experiment(denso, duration=duration, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
        recording, _ = simulate_recording(denso, reference, options, rng, extras=[xp.Spring(1, 40.0, 0.1)])
        save_recording(recording, folder / name)
    return folder


@pytest.fixture(scope="module")
def identified(recordings, tmp_path_factory):
    """identify's model file and page; Coulomb-viscous friction asked: the virtual Denso's LuGre friction opens the
    LuGre trial, about 70 % of the run, which the page does not show (test_held_out_load's identify runs it)."""
    out = tmp_path_factory.mktemp("html_identify") / "model.json"
    argv = ["identify", "denso_vs6556g", "--data", str(recordings / "train.npz"), "--friction", "coulomb-viscous"]
    assert main([*argv, "--validate", str(recordings / "valid.npz"), "--out", str(out)]) == 0
    return out, default_html_path(out)


#: The robots ``psdm diagnose ROBOT``'s run in ``diagnosed`` asked the model cache to derive (one per request).
DERIVED = []


@pytest.fixture(scope="module")
def diagnosed(recordings, tmp_path_factory):
    from psdm_casadi.model_cache import ModelCache

    out = tmp_path_factory.mktemp("html_diagnose") / "diagnosis"
    argv = ["diagnose", str(DENSO_FILE), "--train", str(recordings / "train.npz"), "--validate"]
    argv += [str(recordings / "valid.npz"), "--out", str(out), "--max-effects", "1", "--no-sparse"]
    derive = ModelCache.derive
    with pytest.MonkeyPatch.context() as patch:  # count the derivations (each a cache read, or a full derivation)
        patch.setattr(ModelCache, "derive", lambda self, robot, options=None: DERIVED.append(robot.name) or
                      derive(self, robot, options))  # fmt: skip
        assert main([*argv, "--rigid-body", "prior"]) == 0
    return out / "report.html", json.loads((out / "report.json").read_text())


def test_identify_writes_a_page_holding_the_model_files_numbers(identified):
    out, html = identified
    document, page = json.loads(out.read_text()), html.read_text()
    assert_self_contained(page)
    names = document["robot"]["joint_names"]
    assert page.count('class="psdm-plot joint-plot"') == len(names) == 6
    assert page.index('id="summary"') < page.index("<details")  # the summary first, the details folded below
    assert "Physically consistent" in page and "better than the robot file on" in page
    base = plot_data(page, "parameters-base")[0]
    assert base["x"] == document["base"]["names"]
    np.testing.assert_array_equal(base["y"], document["base"]["values"])
    np.testing.assert_array_equal(base["error_y"]["array"], document["base"]["std"])
    rows = table_rows(page, "Validation RMSE per joint")
    entry = document["validation"]["recordings"][0]
    assert [row[0] for row in rows] == names
    for j, row in enumerate(rows):  # identified, unconstrained, robot file, R^2 as the file holds them
        expected = [entry[k][j] for k in ("rmse", "rmse_ols", "rmse_prior", "r2")]
        np.testing.assert_allclose([float(cell) for cell in row[1:]], expected, rtol=5e-4)
    # the joint plot's measured minus predicted is its residual, and its RMSE the file's validation RMSE
    measured, predicted, residual = plot_data(page, "joint-1-valid.npz")
    np.testing.assert_allclose(np.subtract(measured["y"], predicted["y"]), residual["y"], atol=1e-9)
    assert f"RMSE {entry['rmse'][0]:.4g} N m" in page
    # the summary judges against the model identify replaces too (the file baseline), not only the file alone
    ours, base = np.array(entry["rmse"]), np.array(entry["rmse_robot_file_baseline"])
    assert f"the file baseline, which the never-worse check judges): better on {int(np.sum(ours < base))} of 6" in page


def test_diagnose_writes_a_page_with_each_finding_and_its_before_after(diagnosed):
    html, report = diagnosed
    page = html.read_text()
    assert_self_contained(page)
    assert report["findings"] and report["findings"][0]["effect"] == "spring" and "Found: spring on joint 2" in page
    finding = report["findings"][0]
    before, after = plot_data(page, "finding-1-rmse")
    np.testing.assert_array_equal(before["y"], finding["rmse_before"])
    np.testing.assert_array_equal(after["y"], finding["rmse_after"])
    angle = plot_data(page, "finding-1-angle")
    assert [t["name"] for t in angle][-1] == finding["label"]  # the spring's torque against its joint's angle
    rows = table_rows(page, "Validation RMSE per joint, before and after")
    np.testing.assert_allclose([float(r[1]) for r in rows], report["rmse_before"], rtol=5e-4)
    np.testing.assert_allclose([float(r[2]) for r in rows], report["rmse_after"], rtol=5e-4)


def test_diagnosing_a_robot_file_derives_its_model_once(diagnosed):
    """The robot file's model was derived twice, for the check of the validation recordings' loads
    (``diagnose_loads.robot_file_loads``) and again for the diagnosis: a second cache read, or with ``--no-cache`` a
    second derivation (the Denso's 0.75 s, the Panda's about 20 s)."""
    assert DERIVED == ["Denso VS-6556G"]


def test_the_identify_pages_next_step_names_the_model_file_and_the_recordings(identified):
    """The page said ``psdm codegen MODEL.json``, a placeholder, not the file identify had just written; each next
    step now names the model file (and the diagnosis its recordings), whichever the page's verdict is."""
    from identification.report_html.identify_page import NextFiles, identify_page

    out, html = identified
    page = html.read_text()
    assert "MODEL.json" not in page and "Next: " in page
    document = json.loads(out.read_text())
    files = NextFiles(str(out), f"psdm diagnose {out} --train train.npz --validate valid.npz")
    clean = {**document, "warnings": []}
    text = identify_page(clean, (), files).to_html()
    stem = out.with_suffix("")
    assert f"psdm codegen {out} --out {stem}_c" in text and f"psdm export-urdf {out} {stem}_identified.urdf" in text
    entry = {**document["validation"]["recordings"][0], "r2": [-0.5] + [0.9] * 5}  # joint 1 worse than its mean
    poor = {**clean, "validation": {**document["validation"], "recordings": [entry]}}
    text = identify_page(poor, (), files).to_html()
    assert f"psdm diagnose {out} --train train.npz --validate valid.npz --apply {stem}_2.json" in text
    alone = {**clean, "validation": {}}
    text = identify_page(alone, (), files).to_html()
    assert f"psdm validate {out} OTHER.csv" in text and "--holdout 0.3" in text  # one recording: hold part of it out
    assert "psdm codegen MODEL.json" in identify_page(clean).to_html()  # the Python API: no file written


def _args(tmp_path, **kw):
    values = dict(no_html=False, json=False, html=None, out=str(tmp_path / "m.json"), overwrite=False,
                  robot="denso_vs6556g", model=None, data=[str(tmp_path / "a.csv")], validate=[])  # fmt: skip
    return argparse.Namespace(**{**values, **kw})


def test_the_html_option_defaults_beside_the_model_and_never_replaces_a_file_unasked(tmp_path):
    assert html_output(_args(tmp_path)).target == tmp_path / "m.report.html"
    assert html_output(_args(tmp_path, json=True)) is None  # --json writes no page unless --html asks
    assert html_output(_args(tmp_path, json=True, html=str(tmp_path / "r.html"))).target == tmp_path / "r.html"
    assert html_output(_args(tmp_path, no_html=True)) is None
    (tmp_path / "m.report.html").write_text("mine")
    with pytest.raises(FileExistsError, match="--overwrite"):
        html_output(_args(tmp_path))
    assert html_output(_args(tmp_path, overwrite=True)) is not None


def test_identify_refuses_an_existing_page_before_any_work(recordings, tmp_path, capsys):
    (tmp_path / "r.html").write_text("mine")
    argv = ["identify", "denso_vs6556g", "--data", str(recordings / "train.npz"), "--out", str(tmp_path / "m.json")]
    assert main([*argv, "--html", str(tmp_path / "r.html")]) == 2
    assert "--overwrite" in capsys.readouterr().err and (tmp_path / "r.html").read_text() == "mine"
    assert main([*argv, "--html", str(tmp_path / "r.txt")]) == 2
    assert ".html" in capsys.readouterr().err and not (tmp_path / "m.json").exists()
    folder = ["identify", "denso_vs6556g", "--data", str(recordings), "--protocol", "four-step", "--out"]
    assert main([*folder, str(tmp_path / "out"), "--html", str(tmp_path / "x.html")]) == 2  # not ignored
    assert "no HTML report on this route" in capsys.readouterr().err


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium installed (chromium or chromium-browser on PATH)")
@pytest.mark.parametrize("which", ["identified", "diagnosed"])
def test_the_page_renders_every_plot_in_a_headless_browser_without_console_errors(which, request):
    html = request.getfixturevalue(which)
    html = html[1] if which == "identified" else html[0]
    command = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0",
               "--virtual-time-budget=10000", "--dump-dom", html.resolve().as_uri()]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=120)
    console = [line for line in done.stderr.splitlines() if ":CONSOLE" in line]
    assert console == []
    dom = done.stdout
    plots = dom.split('class="psdm-plot')[1:]
    assert len(plots) >= (8 if which == "identified" else 2)
    assert all("main-svg" in plot for plot in plots)  # plotly drew every figure


def test_the_pages_inline_plotlys_basic_bundle_not_the_full_one(identified, diagnosed):
    """1.2 MB of plotly.js per page instead of 4.8 MB (measured: identify 5.03 -> 1.40 MB, diagnose 4.87 -> 1.24 MB)."""
    from plotly.offline import get_plotlyjs

    full = get_plotlyjs()
    for page in (identified[1].read_text(), diagnosed[0].read_text()):
        assert "plotly.js (basic - minified)" in page and full not in page
        assert len(page.encode()) < len(full.encode()) / 2  # the data stay small beside the bundle


def test_a_trace_outside_the_basic_bundle_gets_the_full_bundle():
    import plotly.graph_objects as go

    from identification.report_html.page import BASIC_TRACES, Page, figure_div

    page = Page("t")
    page.section("line", figure_div(go.Figure(go.Scatter(x=[0, 1], y=[1, 2])), "a"))
    assert not page.needs_full_bundle() and "plotly.js (basic - minified)" in page.to_html()
    page.section("map", figure_div(go.Figure(go.Heatmap(z=[[1, 2], [3, 4]])), "b"))
    assert "heatmap" not in BASIC_TRACES and page.needs_full_bundle()
    assert "plotly.js (basic - minified)" not in page.to_html() and "plotly.js v" in page.to_html()


def test_a_plotly_package_of_another_plotly_js_major_version_gets_its_own_full_bundle(monkeypatch):
    import plotly.offline

    from identification.report_html.page import BUNDLE_VERSION, plotly_bundle

    basic = plotly_bundle()
    vendored = BUNDLE_VERSION.search(basic[:200]).group(1)
    assert vendored.split(".")[0] == plotly.offline.get_plotlyjs_version().split(".")[0]
    monkeypatch.setattr(plotly.offline, "get_plotlyjs_version", lambda: "9.0.0")
    assert plotly_bundle() == plotly.offline.get_plotlyjs() != basic


def test_a_training_recording_with_a_known_load_is_plotted_as_the_fit_weighed_it(denso, denso_model, tmp_path):
    """identify without a held-out recording plots its training recordings. One of them carries a known 2 kg load (its
    sidecar): the fit takes its torque off (``payload_fit.subtract_known_payloads``), but the page plotted the model's
    prediction of the arm against the torque with the load in, a residual of the load's torque. It is now plotted as
    the fit weighed it, the load taken off and said in the title and legend: on every joint the plotted RMSE is the
    fit's training RMSE on that recording (its own preparation and load path, ``trajectory_data.prepare_recordings``),
    and the empty recording is plotted as before."""
    from identification.calibration.calibrated_model import load_calibrated_model
    from identification.calibration.model_preparation import model_preparation
    from identification.calibration.payload_fit import subtract_known_payloads
    from identification.calibration.trajectory_data import prepare_recordings
    from identification.data.configuration import stated_configuration
    from identification.data.io import load_recording

    load = xp.Payload(mass=2.0, com=(0.0, 0.02, 0.06))
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
    for k, (name, extras) in enumerate((("empty.npz", []), ("loaded.npz", [load]))):
        rng = np.random.default_rng(60 + k)
        reference = sine_experiment(denso, duration=6.0, rng=rng).reference()
        save_recording(simulate_recording(denso, reference, options, rng, extras=extras)[0], tmp_path / name)
    (tmp_path / "loaded.payload.json").write_text(json.dumps({"mass": load.mass, "com": list(load.com)}))
    out = tmp_path / "model.json"
    argv = ["identify", "denso_vs6556g", "--data", str(tmp_path / "empty.npz"), str(tmp_path / "loaded.npz")]
    assert main([*argv, "--out", str(out)]) == 0
    page, calibrated = default_html_path(out).read_text(), load_calibrated_model(out)
    preparation = model_preparation(calibrated.document)
    for name in ("empty", "loaded"):
        path = tmp_path / f"{name}.npz"
        _, _, (prepared,) = prepare_recordings(denso, [load_recording(path)], None, preparation.cutoff_hz,
                                               preparation.edge_periods)  # fmt: skip
        (arm,) = subtract_known_payloads(denso, [prepared], [stated_configuration(path)])
        fit_rmse = np.sqrt(np.mean((arm.tau - calibrated.predict(denso_model, arm.q, arm.qd, arm.qdd)) ** 2, axis=0))
        for j in range(denso.n_dof):
            measured, predicted, residual = plot_data(page, f"joint-{j + 1}-{name}.npz")
            plotted = np.sqrt(np.mean(np.square(np.subtract(measured["y"], predicted["y"]))))
            assert plotted == pytest.approx(fit_rmse[j], rel=0.02, abs=0.005), (name, j, plotted, fit_rmse)
            said = "measured, the stated load '2 kg (loaded.payload.json)' (2 kg) taken off"  # its sidecar's name
            assert measured["name"] == (said if name == "loaded" else "measured"), measured["name"]
    assert "training recording, the stated load" in page and "taken off as the fit weighed it" in page
