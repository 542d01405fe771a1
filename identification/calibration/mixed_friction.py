"""Friction per joint: LuGre on some joints, the steady-state shape (Stribeck or Coulomb-viscous) on the others.

identify's LuGre trial (``lugre_trial``) keeps LuGre friction on the joints where it predicts the held-out recordings
better, and the default model's steady-state shape on a joint it makes worse: the bristles' lag is one drive's, and a
joint whose LuGre fit is worse (a wrist whose reversals are too few or too fast to show the bristles) need not cost the
joints that lag their gain. Such a model is fitted as the LuGre route fits every joint (``lugre_identify``), with the
LuGre joints' friction taken out of the torque and their steady-state columns held at 0 in each rigid-body refit
(:func:`mixed_options`), and the other joints' friction columns fitted beside the rigid body as the default model's.

The model file (``calibrated_model``) then holds both: the drive columns of the steady-state shape, 0 on a LuGre joint
(held, standard deviation 0), and ``drive.lugre`` with null on a steady-state joint; ``drive.friction_shapes`` names
each joint's shape (``"lugre"``, ``"stribeck"``, ``"coulomb-viscous"``) and ``drive.lugre.joints`` the LuGre ones.
Every reader predicts a joint by its own shape: the file's torque, the exported C (the drive columns in
``inverse_dynamics``, the LuGre joints' friction in its ``lugre_step``), the URDF and MJCF exports and a diagnosis's
nominal model (``calibrated_model.friction_drives``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import replace

__all__ = ["file_lugre_joints", "file_viscous_exponents", "friction_drives", "mixed_options", "steady_columns",
           "stribeck_start"]  # fmt: skip

#: The friction columns a LuGre joint of a mixed model holds at 0 (its friction is the LuGre block's).
STEADY_TERMS = ("fc", "fs", "fv")


def mixed_options(options, joints, stribeck_velocity):
    """The ``TrajectoryOptions`` of a mixed model's rigid-body refits: ``options`` (the default model's columns, its
    holds dropped: the mixed model is a model of its own, judged as one) with the friction columns of the LuGre
    ``joints`` (0-based) held at 0 and each other joint's steady-state shape kept: its Stribeck velocity of
    ``stribeck_velocity`` (per joint, the default fit's; 0: Coulomb-viscous) held, not searched again. The viscous
    exponents stay every joint's: a LuGre joint's is its LuGre friction's (``lugre_trial``; its columns, held at 0, take
    none of it), which a mixed model's start (:func:`stribeck_start`) fits its LuGre friction from."""
    joints = set(joints)
    held = tuple((f"{term}{j + 1}", 0.0) for j in sorted(joints) for term in ("fc", "fv"))
    changes = {"held_friction": held, "held_links": (), "baseline_friction": ()}
    if "fs" in options.friction:
        vs = tuple(0.0 if j in joints else float(v) for j, v in enumerate(stribeck_velocity))
        shaped = tuple(j for j, v in enumerate(vs) if v > 0)
        changes.update(stribeck_joints=shaped, stribeck_held=vs)
        if not shaped:  # no Stribeck joint left: the steady-state joints are Coulomb-viscous
            changes.update(friction=tuple(t for t in options.friction if t != "fs"), stribeck_joints=None,
                           stribeck_held=None)  # fmt: skip
    return replace(options, **changes)


def file_lugre_joints(document: dict, n_dof: int) -> tuple:
    """The joints (0-based) of a model file's ``drive.lugre`` block: those whose parameters it holds (a file written
    before mixed models holds every joint's); empty without the block."""
    block = document["drive"].get("lugre")
    if not block:
        return ()
    return tuple(j for j in range(n_dof) if block.get("fc", [None] * n_dof)[j] is not None)


def file_viscous_exponents(drive: dict, lugre) -> tuple | None:
    """Each joint's viscous exponent of a model file's ``drive`` block (``TrajectoryOptions.viscous_exponent``): its
    LuGre friction's ``dv`` on a LuGre joint (``lugre``: the file's parameters per joint, None on a steady-state
    joint, or None), ``drive.viscous_exponent``'s on the others (its columns there are the joint's friction; held at 0
    on a LuGre joint, they state 1). None where every joint is linear. A refit of the file starts each LuGre joint's
    fit from its own law (:func:`stribeck_start`)."""
    stated = drive.get("viscous_exponent") or []
    lugre = lugre or ()
    n = max(len(stated), len(lugre))
    exponents = tuple(float(lugre[j].dv) if j < len(lugre) and lugre[j] is not None
                      else float(stated[j]) if j < len(stated) else 1.0 for j in range(n))  # fmt: skip
    return exponents if any(v != 1.0 for v in exponents) else None


def stribeck_start(options):
    """The options of the Stribeck fit of every joint a mixed model's LuGre fits start from where no start is given
    (the refit of a mixed model file, ``lugre_identify``): the steady-state joints' shape and the LuGre joints' holds of
    ``options`` (``mixed_options``) dropped, the Stribeck shape searched on every joint, as ``--friction lugre``
    starts; each joint's viscous exponent kept (a LuGre fit holds its start's, ``lugre_recordings``)."""
    offset = ("offset",) if "offset" in options.friction else ()
    return replace(options, friction=("fc", "fs", "fv", *offset), held_friction=(), stribeck_joints=None,
                   stribeck_held=None)  # fmt: skip


def steady_columns(drive: dict) -> bool:
    """Whether a model file's drive block carries friction columns (a mixed model's steady-state joints) beside its
    LuGre block: a LuGre model of every joint has none."""
    return any(name.rstrip("0123456789") in STEADY_TERMS for name in drive.get("names", ()))


def friction_drives(calibrated, robot) -> tuple | None:
    """Drives carrying the calibrated model's own friction shape, for a nominal model built from it; None for
    Coulomb + viscous (the robot file's drives are kept, their viscous exponents 1 as the file's).

    Stribeck or a viscous power law: ``fc, fs, vs, fv`` and ``dv`` of the file (1 where linear; the bristle values are
    the robot file's and unused by the ``"stribeck"`` diagnosis). LuGre: the seven identified parameters (a mixed
    model: on its LuGre joints; its other joints' steady state as above). The torque
    constants are the robot file's (1 N m/A when it has no drives: the model was then identified from joint torques).
    """
    from psdm_casadi.robot import DriveParameters

    drive, base = calibrated.document["drive"], robot.drives or tuple(DriveParameters() for _ in range(robot.n_dof))
    if drive.get("friction_shape") not in ("stribeck", "lugre") and not drive.get("viscous_exponent"):  # linear
        return None if all(d.dv == 1.0 for d in base) else tuple(dataclasses.replace(d, dv=1.0) for d in base)
    lugre = calibrated.lugre_parameters or (None,) * robot.n_dof  # a mixed model's steady-state joints: None
    if all(p is not None for p in lugre):
        return tuple(dataclasses.replace(d, **p.as_dict()) for d, p in zip(base, lugre))
    values = dict(zip(drive["names"], calibrated.drive))
    vs, dv = drive["stribeck_velocity"] or [0.0] * robot.n_dof, drive.get("viscous_exponent") or [1.0] * robot.n_dof
    flat = [float(v) == 0.0 for v in vs]  # a Coulomb-viscous joint of the file: its static level is its Coulomb one
    return tuple(
        dataclasses.replace(d, fc=max(values[f"fc{j + 1}"], 0.0), vs=d.vs if flat[j] else float(vs[j]),
                            fs=max(values[f"fc{j + 1}" if flat[j] else f"fs{j + 1}"], 0.0),
                            fv=max(values[f"fv{j + 1}"], 0.0), dv=float(dv[j]))
        if lugre[j] is None else dataclasses.replace(d, **lugre[j].as_dict())
        for j, d in enumerate(base)
    )  # fmt: skip
