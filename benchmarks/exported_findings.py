"""Exported equals reported, per benchmark scenario: the calibrated model with a diagnosis' findings, exported.

For one scenario of ``benchmarks/diagnosis.py``: the recordings-route identification on the training
recording (a calibrated model), its recalibration with the report's findings (``recalibrate``), the
CasADi functions ``psdm codegen`` compiles (``build_calibrated_functions``) evaluated on the validation
recording, and the relative difference between that RMSE and the one the new model's file reports.
"""

from __future__ import annotations

import numpy as np

from codegen.calibrated import build_calibrated_functions
from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.recalibrate import recalibrate, validation_rmse
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.metrics import rmse

TOLERANCE = 1e-9


def check_exported(robot, model, robot_source, train, validation, report) -> dict:
    """``{"exported_equals_reported": bool, "exported_rel_error": float, "findings_applied": int}`` of a scenario.

    A scenario whose calibration fails (the error is kept) counts as not reproduced.
    """
    try:
        fit = identify_trajectories(robot, model, [train], TrajectoryOptions())
        calibrated = CalibratedModel.from_fit(robot, model, fit, robot_source=robot_source)
        if report.findings:
            calibrated = recalibrate(
                calibrated, robot, model, report, train, validation, robot_source=robot_source
            ).after
        else:
            calibrated.document["validation"] = {
                "recordings": [{"rmse": validation_rmse(calibrated, model, validation)[0].tolist()}]
            }
        prepared = validation_rmse(calibrated, model, validation)[2]
        function = build_calibrated_functions(calibrated, model, robot, allow_inconsistent=True).inverse_dynamics
        x = (prepared.q, prepared.qd, prepared.qdd)
        tau = np.array(function.map(prepared.n_samples)(*(a.T for a in x)), dtype=float).T
        reported = np.asarray(calibrated.document["validation"]["recordings"][0]["rmse"], dtype=float)
        error = float(np.max(np.abs(rmse(prepared.tau, tau) - reported) / reported))
    except Exception as exc:  # a failed calibration is a result of the benchmark, not a crash of it
        return {"exported_equals_reported": False, "exported_rel_error": None, "exported_error": repr(exc)}
    applied = sum(e["kind"] in ("torque", "signal") for e in calibrated.document["findings"])
    return {"exported_equals_reported": error < TOLERANCE, "exported_rel_error": error, "findings_applied": applied}
