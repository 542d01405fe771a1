"""``psdm identify``'s report on its held-out recordings: per joint the RMSE and R^2 of the model it writes, of the
unconstrained fit and of the robot file, each recording's load (stated, or one nothing states that the data show), and
which part of a ``--holdout`` recording was held out. The model file stores it (``validation``); the text report and
``--json`` print it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["json_numbers", "loads_said", "store_held_out", "validation_report"]


def validation_report(robot, model, fit, recordings, paths, calibrated, configurations) -> dict:
    """Per-joint RMSE [N m] and R^2 on each held-out recording: ours, the unconstrained fit, the prior.

    Ours is the calibrated model's own prediction (``CalibratedModel.predict``, as ``psdm validate``); for a
    LuGre model the unconstrained fit is the Stribeck one it started from. The load each recording carries
    (``configurations``, ``held_out_arm.held_out_configurations``) adds its torque to every prediction (a known load as
    given, an unknown one as identified under its name); a recording that states none, or an unknown one the model has
    not identified, is checked for a load as ``psdm validate`` checks it (``held_out_load``): a plausible one is added
    as well and named (``unstated_payload``, with the RMSE of the load left in).
    """
    from identification.calibration.held_out_load import find_unstated_load
    from identification.calibration.payload_check import validation_with_payload
    from identification.calibration.payload_fit import FlangeRegressor, stated_payload
    from identification.calibration.trajectory_fit import predict_torque
    from identification.data.torque_constants import recording_kt
    from identification.metrics import rmse
    from psdm_casadi.oracle import PinocchioOracle

    out = {"recordings": []}
    prior = PinocchioOracle(robot) if robot.links is not None else None
    for path, recording, configuration in zip(paths, recordings, configurations):
        kt = recording_kt(robot, recording)
        stated, _ = stated_payload(configuration, calibrated.configurations, "the model")
        found = None
        if stated is None:  # nothing stated, or nothing the model weighs: a load the recording shows
            found = find_unstated_load(robot, calibrated, model, recording, kt, str(path))
            error, r2, prepared = found.rmse, found.r2, found.prepared
            stated = found.load.body if found.taken_off else None
        else:
            error, r2, prepared, _ = validation_with_payload(robot, calibrated, model, recording, kt, stated)
        x = (prepared.q, prepared.qd, prepared.qdd)
        load = 0.0 if stated is None else FlangeRegressor(robot)(*x) @ np.asarray(stated, dtype=float)
        ols = predict_torque(model, fit, *x, ols=True) + load
        entry = {"recording": str(path), "rmse": json_numbers(error), "r2": json_numbers(r2),
                 "rmse_ols": json_numbers(rmse(prepared.tau, ols))}  # fmt: skip
        if prior is not None:
            entry["rmse_prior"] = json_numbers(rmse(prepared.tau, prior.rnea(*x) + load))
        if found is not None and found.load is not None:
            left_in = json_numbers(found.rmse_left_in)
            entry["unstated_payload"] = {
                **found.load.to_dict(),
                "rmse_load_left_in": left_in,
                "sentence": found.load.sentence(left_in if found.taken_off else None),
            }
        out["recordings"].append(entry)
    return out


def loads_said(report, judged, args) -> list:
    """Per held-out recording, the one line on the load nothing states that it carries (None: none): the report's
    (``unstated_payload``), with what the judges took off where the report did not take that off; each validation
    entry records the latter (``judged_without_load``)."""
    out = []
    for path, entry, load in zip(args.validate, report["recordings"], judged.loads):
        taken = load is not None and load.plausible
        entry.update({"judged_without_load": load.judged()} if taken else {})
        named = entry.get("unstated_payload") or {}
        judges = judged.said(path, load) if taken and not named.get("taken_off") else None
        out.append(" ".join(filter(None, (named.get("sentence"), judges))) or None)
    return out


def store_held_out(args, report, calibrated, given: int) -> None:
    """The held-out parts in the validation report (after the ``given`` ``--validate`` recordings) and in the model
    file (``identification.holdout``), where validate and diagnose find them again."""
    from identification.data.holdout import holdout_block

    for entry, part in zip(report["recordings"][given:], args.held_out):
        entry["held_out"] = part.to_dict()
    if args.held_out:
        calibrated.document["identification"]["holdout"] = holdout_block(args.held_out)


def json_numbers(values) -> list:
    return [float(v) if np.isfinite(v) else None for v in np.atleast_1d(values)]  # None: a joint without torque
