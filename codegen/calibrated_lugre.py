"""The LuGre friction of a calibrated model as C: the bristle step a controller carries (calibrated model -> C).

A calibrated model identified with ``--friction lugre`` (``identification.calibration.lugre_recordings``)
has friction that depends on the bristle state ``s = sigma0 z`` [N m] of each joint, carried along the
samples. Its ``inverse_dynamics`` (``codegen.calibrated``) is the rigid body, drive inertias, offsets and
findings without friction; this module exports beside it, into ``<library>_lugre.c`` / ``.h``:

    <prefix>lugre_step(s[n], qd_prev[n], qd[n], dt) -> (s_next[n], tau_friction[n])

one step of the exponential integrator of ``identification.friction.lugre_step`` over a sample interval
``dt`` [s] with the velocity linear from ``qd_prev`` to ``qd`` (split at a zero crossing, as
``substep_layout`` splits it), and the LuGre friction torque (eq. 14) at the new sample. It is the step
``psdm validate`` and ``CalibratedModel.predict`` take (``simulation.simulate_lugre``, one sub-step), so
the feed-forward ``inverse_dynamics(q, qd, qdd) + tau_friction`` carried along a recording reproduces the
reported torque. Start with ``s = 0`` (relaxed, a robot at rest); ``dt = 0`` with ``qd_prev = qd`` gives
the friction of the current state without advancing it.
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca

from identification.friction.expressions import lugre_step_expression, lugre_torque_expression

__all__ = ["LUGRE_STEP", "add_lugre_step", "build_lugre_step", "lugre_note"]

#: Name of the exported step Function (the C symbol is the prefix plus this).
LUGRE_STEP = "lugre_step"


def build_lugre_step(calibrated) -> ca.Function | None:
    """``lugre_step(s, qd_prev, qd, dt) -> (s_next, tau_friction)`` of a LuGre model (module docstring), else None.

    Parameters
    ----------
    calibrated : identification.calibration.calibrated_model.CalibratedModel

    Returns
    -------
    casadi.Function or None
        Inputs ``s`` (n_dof) [N m], ``qd_prev``, ``qd`` (n_dof) [rad/s], ``dt`` (1) [s]; outputs ``s_next`` (n_dof)
        [N m] and ``tau_friction`` (n_dof) [N m]; the parameters compiled in.
    """
    parameters = calibrated.lugre_parameters
    if parameters is None:
        return None
    n = len(parameters)
    s, qd_prev, qd = (ca.SX.sym(name, n) for name in ("s", "qd_prev", "qd"))
    dt = ca.SX.sym("dt")
    s_next, tau = [], []
    for j, p in enumerate(parameters):
        if p is None:  # a mixed model's steady-state joint: its friction is in inverse_dynamics, its state unused
            s_next.append(s[j])
            tau.append(ca.SX(0.0))
            continue
        values = ca.DM(p.as_array())
        a, b = qd_prev[j], qd[j]
        crossing = a * b < 0
        fraction = ca.if_else(crossing, a / ca.if_else(crossing, a - b, 1.0), 1.0)
        middle = ca.if_else(crossing, 0.0, b)
        first = lugre_step_expression(s[j], a, middle, dt * fraction, values)
        second = lugre_step_expression(first, 0.0, b, ca.if_else(crossing, dt * (1.0 - fraction), 0.0), values)
        s_next.append(second)
        tau.append(lugre_torque_expression(second / p.sigma0, b, values))
    return ca.Function(
        LUGRE_STEP, [s, qd_prev, qd, dt], [ca.vertcat(*s_next), ca.vertcat(*tau)],
        ["s", "qd_prev", "qd", "dt"], ["s_next", "tau_friction"], {"cse": True},
    )  # fmt: skip


def lugre_note(calibrated, prefix: str = "psdm_") -> list:
    """Header lines that say where a LuGre model's friction is (empty for other models)."""
    parameters = calibrated.lugre_parameters
    if parameters is None:
        return []
    joints = [j + 1 for j, p in enumerate(parameters) if p is not None]
    where = "" if len(joints) == len(parameters) else f" (joints {joints}; the others' friction is in it)"
    lines = [
        f"LuGre friction{where} is NOT in {prefix}inverse_dynamics (nor in bias, gravity, forward_dynamics): it "
        f"depends on the bristle state. {prefix}{LUGRE_STEP}(s, qd_prev, qd, dt) -> (s_next, tau_friction) in the "
        "_lugre files advances the bristle force s = sigma0 z [N m] of every joint over a sample interval dt [s] "
        "(velocity linear from qd_prev to qd) and gives the friction torque at the new sample; the full feed-forward "
        f"is {prefix}inverse_dynamics(q, qd, qdd) + tau_friction. Carry s between calls, start with s = 0 (at rest).",
        "LuGre parameters per joint (fc, fs, vs, fv, dv, sigma0, sigma1):",
    ]
    lines += [f"  joint {j + 1}: " + ("no LuGre friction: its steady-state friction is in inverse_dynamics, "
                                      "tau_friction 0 and s unchanged" if p is None else
                                      ", ".join(f"{v:.17g}" for v in p.as_array()))
              for j, p in enumerate(parameters)]  # fmt: skip
    return lines


def add_lugre_step(export, calibrated, note: str = "") -> Path | None:
    """Write ``<library>_lugre.c`` and ``.h`` with the step of a LuGre model into an export's folder.

    Parameters
    ----------
    export : codegen.export.CExport
        The export of the model's other Functions (its folder, library name and prefix are used).
    calibrated : CalibratedModel
    note : str
        A C comment put at the top of both files.

    Returns
    -------
    Path or None
        The ``.c`` file, or None for a model without LuGre friction.
    """
    step = build_lugre_step(calibrated)
    if step is None:
        return None
    prefix = _prefix(export)
    library = f"{export.library}_lugre"
    renamed = ca.Function(prefix + LUGRE_STEP, step.sx_in(), step.call(step.sx_in()), step.name_in(), step.name_out())
    generator = ca.CodeGenerator(f"{library}.c", {"with_header": True})
    generator.add(renamed)
    generator.generate(str(export.folder) + "/")
    source, header = Path(export.folder) / f"{library}.c", Path(export.folder) / f"{library}.h"
    for path in (source, header):
        path.write_text(note + path.read_text())
    return source


def _prefix(export) -> str:
    """The C symbol prefix of an export (``psdm_`` unless its functions say otherwise)."""
    names = [name for name in export.function_names if name.endswith("inverse_dynamics")]
    return names[0][: -len("inverse_dynamics")] if names else "psdm_"
