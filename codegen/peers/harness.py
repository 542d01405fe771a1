"""What the C++ speed harnesses share: running a build or benchmark command, and the Pinocchio model as C++.

``codegen.peers.speed`` (one call), ``codegen.peers.batch_speed`` (batches) and ``codegen.peers.cppadcg``
(Pinocchio's CppADCodeGen code) compile and run C++ programs that rebuild the Python Pinocchio model joint by
joint; they do it with these functions so that every harness times the same model and reports a failed
command the same way.
"""

from __future__ import annotations

import os
import subprocess

import numpy as np

from psdm_casadi.errors import SolverError

__all__ = ["cpp_model_code", "cpp_numbers", "run_command"]


def run_command(command, cwd, env=None) -> str:
    """Run ``command`` in ``cwd`` (``env`` added to the environment); its stdout, or SolverError with the last
    lines of its stderr."""
    proc = subprocess.run(
        command, cwd=cwd, capture_output=True, text=True, env=None if env is None else {**os.environ, **env}
    )
    if proc.returncode != 0:
        tail = "\n".join(proc.stderr.strip().splitlines()[-20:])
        raise SolverError(f"`{' '.join(command)}` failed ({proc.returncode}):\n{tail}")
    return proc.stdout


def cpp_numbers(values) -> str:
    """Comma-separated doubles, row by row, for a C++ initialiser."""
    return ", ".join(repr(float(v)) for v in np.asarray(values, dtype=float).ravel())


def cpp_model_code(pin_model) -> str:
    """C++ lines adding every joint of a Python pin.Model (revolute or prismatic) with its placement and inertia.

    The harness template declares ``model``, ``rotation``, ``translation``, ``lever``, ``inertia`` and ``jid``.
    """
    lines = []
    for jid in range(1, pin_model.njoints):
        joint = pin_model.joints[jid]
        short = joint.shortname()
        if short in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
            built = f"pinocchio::{short}(Eigen::Vector3d({cpp_numbers(joint.extract().axis)}))"
        elif short[:-1] in ("JointModelR", "JointModelP") and short[-1] in "XYZ":
            built = f"pinocchio::{short}()"
        else:
            raise SolverError(f"joint type {short} is not supported by the speed harness; use revolute joints.")
        placement, inertia = pin_model.jointPlacements[jid], pin_model.inertias[jid]
        lines += [
            f"  rotation << {cpp_numbers(placement.rotation)};",  # Eigen's comma initialiser fills row by row
            f"  translation << {cpp_numbers(placement.translation)};",
            f"  jid = model.addJoint({pin_model.parents[jid]}, {built}, pinocchio::SE3(rotation, translation), "
            f'"{pin_model.names[jid]}");',
            f"  lever << {cpp_numbers(inertia.lever)};",
            f"  inertia << {cpp_numbers(inertia.inertia)};",
            f"  model.inertias[jid] = pinocchio::Inertia({float(inertia.mass)!r}, lever, inertia);",
        ]
    return "\n".join(lines)
