"""A model ``diagnose --apply`` wrote is not told its own findings again (``diagnosis.carried_terms``,
``model_file.file_corrected``, ``calibration.model_file_holds``).

Reference: the virtual Denso's hidden truth, torque sensors with 0.1 N m noise and no friction: a torque ripple 1.5
sin(6 q2 + 0.4) N m on joint 2, a coupling 0.6 qd6 N m on joint 5, and the torque signal 4 samples (8 ms at 500 Hz)
behind the motion (6 s of training, 3 s held out). The model file is the one ``--apply`` writes with those three
findings (``applied_model``'s ``finding_terms`` and ``joint_fit``, its one builder). Diagnosed again on the same
recordings, its ripple and coupling are columns of the nominal model (kept, fitted again to the truth's sizes) and its
delay corrects the recordings as the file does: nothing is found again. Before, the nominal model left all three out and
the diagnosis found them again, telling the user to add what the model already has.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.applied_model import finding_terms, joint_fit
from identification.calibration.calibrated_model import CalibratedModel, read_calibrated_model
from identification.calibration.model_file_holds import model_file_holds
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.diagnosis.candidates import CandidateLibrary, CouplingTerm, DelayTerm, TorqueRippleTerm
from identification.diagnosis.carried_terms import KEPT_NOTE, CarriedColumns, carried_candidates
from identification.diagnosis.diagnose import DiagnosisOptions
from identification.diagnosis.model_file import diagnose_model
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

AMPLITUDE, HARMONIC, PHASE = 1.5, 6, 0.4
VISCOUS, DELAY_S, RATE = 0.6, 0.008, 500.0
RIPPLE, COUPLING = TorqueRippleTerm(joint=1, harmonic=HARMONIC), CouplingTerm(joint=4, source=5)


def _finding(term, coefficients, parameters):
    """A diagnosis finding of ``term`` as ``finding_terms`` reads it from a report."""
    return SimpleNamespace(effect=term.key, label=term.label, joints=term.joints, coefficients=tuple(coefficients),
                           parameters=parameters, feature_names=tuple(term.feature_names()), rmse_before=(),
                           rmse_after=())  # fmt: skip


@pytest.fixture(scope="module")
def applied(denso, denso_model, tmp_path_factory):
    """``(written document, its diagnosis)``: the model file identified with the three findings as ``--apply``
    writes it, then diagnosed on the same training recording and the 4 s held out (the effects' own library)."""
    coupling = np.zeros((denso.n_dof, denso.n_dof))
    coupling[4, 5] = VISCOUS
    extras = [xp.TorqueRipple(joint=1, amplitude=AMPLITUDE, harmonic=float(HARMONIC), phase=PHASE),
              xp.JointCoupling(matrix=coupling), xp.SignalDelay(samples=round(DELAY_S * RATE))]  # fmt: skip
    rng = np.random.default_rng(3)
    reference = sine_experiment(denso, duration=9.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False, rate=RATE)
    recording, _ = simulate_recording(denso, reference, options, rng, extras=extras)
    train, validation = recording.time_slice(-np.inf, 6.0), recording.time_slice(6.0, np.inf)
    fit = identify_trajectories(denso, denso_model, [train], TrajectoryOptions())
    before = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    terms = (RIPPLE, COUPLING, DelayTerm())
    ripple = AMPLITUDE * np.array([np.cos(PHASE), np.sin(PHASE)])
    findings = (_finding(RIPPLE, ripple, {}), _finding(COUPLING, (VISCOUS, 0.0), {}),
                _finding(terms[2], (DELAY_S,), {"delay_s": DELAY_S}))  # fmt: skip
    report = SimpleNamespace(findings=findings, augmented=SimpleNamespace(terms=terms, coefficients=[
        f.coefficients for f in findings]))  # fmt: skip
    after, _ = joint_fit(before, denso, denso_model, [train], finding_terms(before, report), DENSO_FILE)
    path = tmp_path_factory.mktemp("applied") / "new.json"
    after.save(path)
    loaded = read_calibrated_model(path, derive=lambda robot: denso_model)
    library = CandidateLibrary((TorqueRippleTerm(harmonics=(3, 6)), CouplingTerm(), DelayTerm()))
    options = DiagnosisOptions(library=library, rigid_body="prior", sparse=False, cv_folds=0)
    return after.document, diagnose_model(loaded, train, [validation], options)


def test_the_written_file_holds_the_three_findings_near_the_truth(applied):
    document, _ = applied
    entries = {e["label"]: e for e in document["findings"]}
    assert set(entries) == {RIPPLE.label, COUPLING.label, "delay"}
    assert entries[RIPPLE.label]["parameters"]["amplitude"] == pytest.approx(AMPLITUDE, rel=0.05)
    assert entries[COUPLING.label]["parameters"]["viscous"] == pytest.approx(VISCOUS, rel=0.05)
    assert document["corrections"]["delay"]["delay_s"] == DELAY_S


def test_a_ripple_the_file_holds_is_kept_not_found_again(applied):
    _, report = applied
    ripples = [f for f in report.findings if f.effect == "torque_ripple"]
    assert [(f.label, f.shape_note) for f in ripples] == [(RIPPLE.label, KEPT_NOTE)]  # main: found again, no note
    assert ripples[0].parameters["amplitude"] == pytest.approx(AMPLITUDE, rel=0.05)  # fitted again: the truth's
    assert any(f"`{RIPPLE.label}`: amplitude = " in note and "in the file" in note for note in report.rigid_body_notes)


def test_a_coupling_the_file_holds_is_kept_not_found_again(applied):
    _, report = applied
    couplings = [f for f in report.findings if f.effect == "coupling"]
    assert [(f.label, f.shape_note) for f in couplings] == [(COUPLING.label, KEPT_NOTE)]
    assert couplings[0].parameters["viscous"] == pytest.approx(VISCOUS, rel=0.05)


def test_a_delay_the_file_corrects_is_applied_to_the_recordings_not_found_again(applied):
    """The file's corrections applied, the diagnosis's "before" is the file's own validation RMSE (``psdm validate``'s:
    main compared an uncorrected nominal, several times the file's error on joints 1-2, and found the delay again)."""
    _, report = applied
    assert [f.label for f in report.findings if f.effect == "delay"] == []
    assert [f.label for f in report.findings if f.shape_note != KEPT_NOTE] == []  # nothing new at all
    np.testing.assert_allclose(report.rmse_before, report.model_file_rmse, rtol=1e-6)
    assert any("measurement corrections (`delay`) are applied" in note for note in report.rigid_body_notes)


def test_every_torque_finding_of_a_file_is_carried_by_its_own_label():
    """``model_file_holds`` -> ``carried_candidates``: each finding's own term (main carried the springs alone and
    read any other term as a linear spring); the library still offers a ripple of another harmonic, a coupling from
    another joint (main covered every term of a carried effect on its joints)."""
    document = {"findings": [
        {"label": RIPPLE.label, "kind": "torque", "term": {"effect": "torque_ripple", "joint": 2, "harmonic": 6}},
        {"label": COUPLING.label, "kind": "torque", "term": {"effect": "coupling", "joint": 5, "source": 6}},
        {"label": "coulomb_asymmetry[j3]", "kind": "torque", "term": {"effect": "coulomb_asymmetry", "joint": 3}},
        {"label": "delay", "kind": "signal"},
    ]}  # fmt: skip
    terms = carried_candidates(model_file_holds(document).torque_terms)
    assert [t.label for t in terms] == [RIPPLE.label, COUPLING.label, "coulomb_asymmetry[j3]"]
    assert [t.joints for t in terms] == [(1,), (4, 5), (2,)]
    carried = CarriedColumns(terms)
    assert carried.covers(TorqueRippleTerm(joint=1, harmonic=6)) and carried.covers(CouplingTerm(joint=4, source=5))
    assert not carried.covers(TorqueRippleTerm(joint=1, harmonic=3)) and not carried.covers(
        CouplingTerm(joint=4, source=3)
    )
    assert not carried.covers(CouplingTerm(joint=5, source=4))  # the other direction: another effect
    DiagnosisOptions(carried=terms)  # a coupling (two joints) is carried as any other
