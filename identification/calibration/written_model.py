"""The model ``psdm identify`` writes from a fit: the steps that follow it, and the robot-file check of their result.

The fit is not what identify writes. The counterbalance route (``counterbalance_column``) and the payload route
(``payload_route``) follow it and take over torque the fit's links had absorbed: on a heavy arm with a balancer on
joint 2 the fit without the spring is worse than the robot file on joint 1, the model with it is not. identify's holds
(``one_way_friction``, ``worse_joint_hold``) decide from the robot-file check (``robot_file_check``) whether a fit's
friction or links are held at the robot file's; judged on the fit, they held every link of that arm at the robot
file's (its masses some 10 % off) for a deficit the written model does not have. So a candidate fit is carried through
the steps that follow it (:class:`ModelWriter`), and the check judges their result (:class:`WrittenModel`): the holds
act only where the model identify would write is worse than the robot file, and the model they keep is written as
judged, without carrying it through again.
"""

from __future__ import annotations

from dataclasses import dataclass

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.counterbalance_column import CounterbalanceChoice, take_counterbalance
from identification.calibration.file_judged import FileJudged, file_check
from identification.calibration.payload_route import PayloadChoice, take_payload
from identification.calibration.robot_file_check import FileCheck

__all__ = ["ModelWriter", "WrittenModel"]


@dataclass(frozen=True, eq=False)
class WrittenModel:
    """A fit carried to the model file identify writes (:class:`ModelWriter`).

    ``start``: the fit before the counterbalance (made with ``options``); ``fit``: the fit written (a kept
    counterbalance's, or the payload's); ``calibrated``: the model file; ``counterbalance``, ``payload``: what the two
    routes decided; ``check``: ``calibrated`` against the robot file on the held-out recordings it is judged on.
    """

    start: object
    options: object
    fit: object
    calibrated: CalibratedModel
    counterbalance: CounterbalanceChoice
    payload: PayloadChoice
    check: FileCheck


class ModelWriter:
    """``writer(options, fit) -> WrittenModel``: ``fit`` (made with ``options``) through the counterbalance route, the
    payload route and a drive loss, and the result checked against the robot file; each ``(options, fit)`` carried
    once (a hold judges a fit and the route then writes it).

    ``problem = (robot, model, recordings, configurations)`` of the training recordings; ``validation`` the raw
    held-out recordings the routes judge on; ``judged`` the ``file_judged.FileJudged`` ones the robot file is judged
    on; ``saved`` the model file's keywords and the recordings' paths (``counterbalance_column.take_counterbalance``);
    ``skip``: a route that takes no extra columns; ``loss``: the drive loss's ``(joints, values)`` of
    ``drive_loss.identify_with_drive_loss`` (empty: none); ``columns``: the fit whose friction columns the robot
    file's friction is fitted with in the check (a LuGre model's Stribeck start; None: the fit's own)."""

    def __init__(self, problem, validation, judged: FileJudged, saved, skip: bool, loss=(), columns=None):
        self.problem, self.validation, self.judged = tuple(problem), list(validation), judged
        self.saved, self.skip, self.loss, self.columns = saved, skip, tuple(loss), columns
        self._written = []  # (options, fit, WrittenModel): by identity, the objects kept alive

    def __call__(self, options, fit) -> WrittenModel:
        for known_options, known_fit, written in self._written:
            if known_options is options and known_fit is fit:
                return written
        robot, model, recordings, configurations = self.problem
        steps = (robot, model, recordings, options, configurations)
        final, calibrated, taken = take_counterbalance(steps, fit, self.validation, self.saved, self.skip)
        final, calibrated, taken, payload = take_payload(steps, fit, taken, calibrated, self.validation, self.saved,
                                                         self.skip)  # fmt: skip
        if self.loss:
            from identification.calibration.drive_loss import with_drive_loss

            calibrated = CalibratedModel(with_drive_loss(calibrated.document, *self.loss))
        check = file_check(steps, self.judged, final, calibrated, self.columns)
        written = WrittenModel(fit, options, final, calibrated, taken, payload, check)
        self._written.append((options, fit, written))
        return written
