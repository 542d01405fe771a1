"""What identify holds by choice (``worse_joint_hold``: friction at the robot file's baseline, links at the file's) is
not evidence of what the data want (``held_back``, the envelope's named effect).

References: an unstated 2 kg tool on the virtual Denso (friction-free sensors: the true friction is 0), whose fit
without any hold names a payload; the unconstrained least squares, which a held column the data's own fit frees
cannot change (its columns are the same), and the model's parameter map (which base parameters combine only the held
links' inertial parameters).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.consistent_fit import held_rotors
from identification.calibration.held_back import stored_held_back
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual import effects as xp
from tests.identification.diagnosis_data import rigid_recording

TOOL = xp.Payload(mass=2.0, com=np.array([0.05, 0.0, 0.15]))
WRONG = (("fc4", 1.0), ("fv4", 0.0))  # joint 4's friction held 1 N m off the truth (0)


HELD_LINKS = (4, 5)  # links 5 and 6 held at the file's while the tool's torque asks them for more


@pytest.fixture(scope="module")
def tool_recording(denso):
    return rigid_recording(denso, [TOOL])


@pytest.fixture(scope="module")
def held_fit(denso, denso_model, tool_recording):
    return identify_trajectories(denso, denso_model, [tool_recording], TrajectoryOptions(held_links=HELD_LINKS))


def test_friction_held_at_the_baseline_leaves_the_datas_own_estimate_and_the_named_payload(
    denso, denso_model, tool_recording
):
    """Held as ``worse_joint_hold`` holds it (``baseline_friction``), what the fit is compared with is the data's own
    least squares of the fit without the hold (the same columns, the held torque taken off and fitted back; within a
    quarter of a standard deviation, as the joints' weights move a little): the same parameters named, at the same
    values the data want, and the tool still a payload. Held as the one-way hold holds it (the data's own fit holds it
    too), what the data want moves by more: the choice would pass for evidence."""
    free = identify_trajectories(denso, denso_model, [tool_recording], TrajectoryOptions())
    options = TrajectoryOptions(held_friction=WRONG, baseline_friction=("fc4", "fv4"))
    chosen = identify_trajectories(denso, denso_model, [tool_recording], options)
    plain = identify_trajectories(denso, denso_model, [tool_recording], TrajectoryOptions(held_friction=WRONG))
    k = chosen.drive_names.index("fc4")
    assert chosen.drive[k] == 1.0 and chosen.drive_std[k] == 0  # held in the fit
    wanted = {h.parameter: h for h in stored_held_back(free.envelope_bounds)}
    items = stored_held_back(chosen.envelope_bounds)
    assert items and all(h.absorbs == "payload" for h in items), [(h.words, h.absorbs) for h in items]
    assert {h.parameter for h in items} == set(wanted)
    assert all(abs(h.data - wanted[h.parameter].data) < 0.25 * wanted[h.parameter].data_std for h in items)
    moved = [abs(h.data - wanted[h.parameter].data) / wanted[h.parameter].data_std
             for h in stored_held_back(plain.envelope_bounds) if h.parameter in wanted]  # fmt: skip
    assert {h.parameter for h in stored_held_back(plain.envelope_bounds)} != set(wanted) or max(moved) > 1.0


def test_links_held_at_the_robot_files_are_not_named_as_held_back_by_the_data(denso_model, held_fit):
    """Links 5 and 6 held at the file's (``held_links``) while the tool's torque asks them for more: a base parameter
    of those links alone is held there by the choice, not named; what the choice leaves (parameters that combine a
    free link's) still is (before, the tool's inertia of link 6 was named a parameter held back)."""
    held_links, fit = HELD_LINKS, held_fit
    blocks = np.abs(denso_model.parameter_map).reshape(denso_model.n_base, len(fit.standard), -1) > 0

    def only_held(name):
        row = blocks[denso_model.base_names.index(name)]
        return not np.any(np.delete(row[:, :10], held_links, axis=0)) and not np.any(row[:, 10:])

    named = stored_held_back(fit.envelope_bounds)
    assert not any(only_held(h.parameter) for h in named), [h.parameter for h in named]


def test_held_rotors_are_those_of_the_joints_whose_every_carried_link_is_held(denso):
    """The rule (``consistent_fit.held_rotors``): in a serial chain joint j carries links j to the flange, so its
    rotor is held only where all of them are; a joint whose file states no rotor has nothing to hold it at."""
    assert held_rotors(denso, (4, 5)) == (4, 5)
    assert held_rotors(denso, (3, 5)) == (5,)  # link 4 held, link 5 free: joint 4's rotor stays fitted
    assert held_rotors(denso, (0,)) == () and held_rotors(denso, ()) == ()
    assert held_rotors(denso, tuple(range(6))) == tuple(range(6))
    without = replace(denso, rotor_inertia=np.where(np.arange(6) == 5, 0.0, denso.rotor_inertia))
    assert held_rotors(without, (4, 5)) == (4,)


def test_a_joint_whose_carried_links_are_held_keeps_the_robot_files_rotor(denso, denso_model, tool_recording):
    """Known truth (the file is the virtual Denso's): links 4 and 6 held at the file's while the tool's torque asks the
    wrist for more. Joint 6 carries link 6 alone, all of it held: its drive inertia is held at the file's (the truth)
    with it, and no bound is named pushed for it (held there, not by the data). Joint 4 carries links 4-6, link 5
    free: its drive inertia stays fitted, off the file's (a rotor held with its own link alone fixed that joint's
    torque while the free links after it took what the data ask of it: a heavy arm then kept a spring it does not
    have)."""
    fit = identify_trajectories(denso, denso_model, [tool_recording], TrajectoryOptions(held_links=(3, 5)))
    rotors = np.asarray(fit.standard, dtype=float)[:, -1]
    file = np.asarray(denso.rotor_inertia, dtype=float)
    assert rotors[5] == pytest.approx(file[5], rel=1e-9)
    assert abs(rotors[3] - file[3]) > 1e-3 * file[3], (rotors[3], file[3])
    assert not [f for f in fit.envelope if f.link == 5 and any("drive" in b for b in f.bounds)]
