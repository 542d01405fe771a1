"""Pinocchio's own code generation (CppADCodeGen) as a peer of the speed benchmark (codegen.peers.speed).

A small C++ generator (``templates/cppadcg_gen.cpp``, compiled once per benchmark run and cached in the
run's build folder) reads a robot's Pinocchio model from a text file and writes the C sources that
CppADCodeGen generates for Pinocchio's CodeGenRNEA and CodeGenABA (each with its Jacobian in
(q, v, a|tau)), CodeGenRNEADerivatives, CodeGenABADerivatives and the joint torque regressor. The harness
compiles them with its own flags and calls the generated functions directly (no dynamic-library
indirection). Needs the ``cmeel-cppad`` and ``cmeel-cppadcodegen`` wheels (the ``bench`` extra).
"""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import numpy as np

from codegen.peers.harness import run_command
from psdm_casadi.errors import SolverError

GENERATOR_SOURCE = Path(__file__).resolve().parent / "templates" / "cppadcg_gen.cpp"
# Generated models: (name, input, output size as a C++ expression of n and n_regressor).
MODELS = (
    ("rnea", "forward_zero", "n"),
    ("aba", "forward_zero", "n"),
    ("regressor", "forward_zero", "n * n_regressor"),
    ("rnea", "jacobian", "3 * n * n"),
    ("aba", "jacobian", "3 * n * n"),
    ("rnea_derivatives", "forward_zero", "3 * n * n"),
    ("aba_derivatives", "forward_zero", "3 * n * n"),
)
# The generator only runs once per robot: optimising it is not worth its compile time.
GENERATOR_FLAGS = ("-O0",)
INSTALL_HINT = "pip install cmeel-cppad cmeel-cppadcodegen (or pip install -e '.[bench]')"


def c_function(name: str, kind: str = "forward_zero") -> str:
    """The C symbol CppADCodeGen generates for a model's function (``rnea_forward_zero``, ``aba_jacobian``), in
    ``<name>_<kind>.c``: ``void f(double const* const* in, double* const* out, struct LangCAtomicFun atomic)``
    with ``in[0]`` the packed input vector and ``out[0]`` the output (Jacobians row-major)."""
    return f"{name}_{kind}"


def check_headers(include: Path) -> None:
    """Raise SolverError naming what to install when CppAD, CppADCodeGen or Pinocchio's codegen headers are missing."""
    for header, package in (
        ("cppad/cppad.hpp", "cmeel-cppad"),
        ("cppad/cg.hpp", "cmeel-cppadcodegen"),
        ("pinocchio/codegen/cppadcg-algo.hpp", "pin"),
    ):
        if not (include / header).exists():
            raise SolverError(f"{header} not found under {include} (the {package} wheel); install it: {INSTALL_HINT}")


def build_generator(cache: Path, eigen: Path, include: Path, defines, log) -> Path:
    """The compiled generator, from ``cache`` when an identical build is there (keyed by source and flags)."""
    check_headers(include)
    source = GENERATOR_SOURCE.read_text()
    digest = hashlib.sha1((source + " ".join((*GENERATOR_FLAGS, *defines, str(include)))).encode()).hexdigest()[:12]
    exe = Path(cache) / f"cppadcg_gen_{digest}"
    if exe.exists():
        return exe
    Path(cache).mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    partial = exe.with_suffix(".partial")
    command = ["c++", *GENERATOR_FLAGS, "-std=c++17", *defines, f"-I{eigen}", f"-I{include}", "-w"]
    run_command([*command, str(GENERATOR_SOURCE), "-o", str(partial), "-ldl"], cache)
    partial.replace(exe)
    log(f"CppADCodeGen generator compiled in {time.perf_counter() - t0:.0f} s")
    return exe


def _numbers(values) -> str:
    return " ".join(repr(float(v)) for v in np.asarray(values, dtype=float).ravel())


def write_model_file(pin_model, path: Path) -> None:
    """The text file the generator reads: joints (parent, type, axis, placement, inertia), armature, gravity."""
    lines = [str(pin_model.njoints)]
    for jid in range(1, pin_model.njoints):
        joint = pin_model.joints[jid]
        short = joint.shortname()
        axis = joint.extract().axis if "Unaligned" in short else np.zeros(3)
        placement, inertia = pin_model.jointPlacements[jid], pin_model.inertias[jid]
        lines.append(
            f"{pin_model.parents[jid]} {short} {_numbers(axis)} {_numbers(placement.rotation)} "
            f"{_numbers(placement.translation)} {float(inertia.mass)!r} {_numbers(inertia.lever)} "
            f"{_numbers(inertia.inertia)}"
        )
    lines.append(_numbers(pin_model.armature))
    lines.append(_numbers(pin_model.gravity.linear))
    Path(path).write_text("\n".join(lines) + "\n")


def generate_sources(generator: Path, pin_model, folder: Path) -> list:
    """Run the generator for one robot; returns the generated C files (in ``folder``)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_model_file(pin_model, folder / "model.txt")
    run_command([str(generator), "model.txt", "."], folder)
    sources = sorted(folder.glob("*.c"))
    if not sources:
        raise SolverError(f"the CppADCodeGen generator wrote no C file into {folder}")
    return sources


HELPERS = """
// A CppADCodeGen-generated function (one packed input vector, one output array), called directly.
struct CppadcgCall {
  typedef void (*fn_t)(double const* const*, double* const*, struct LangCAtomicFun);
  fn_t fn;
  std::vector<double> out;
  LangCAtomicFun atomic{nullptr, nullptr, nullptr};
  CppadcgCall(fn_t f, long size) : fn(f), out(size) {}
  inline const double* operator()(const double* x) {
    const double* in[1] = {x};
    double* res[1] = {out.data()};
    fn(in, res, atomic);
    return out.data();
  }
};
"""

# Checks against Pinocchio on the check states: values, the regressor entry by entry, and the derivatives
# (references stored [value, d/dq, d/dv, d/d(a|tau)] column-major; CppADCodeGen's are row-major; the
# third block of CodeGen*Derivatives is not compared, Pinocchio fills only its upper triangle).
CHECKS = """
  auto cppadcg_error = [&](CppadcgCall& f, const std::vector<double>& X, const std::vector<Eigen::VectorXd>& ref,
                           int) {
    double err = 0;
    for (long k = 0; k < n_check; ++k) {
      const double* x = f(&X[3 * n * k]);
      for (int i = 0; i < n; ++i) err = std::max(err, std::abs(x[i] - ref[k][i]));
    }
    return err;
  };
  auto cppadcg_regressor_error = [&](CppadcgCall& f, int n_columns) {
    double err = 0;
    for (long k = 0; k < n_check; ++k) {
      const Eigen::MatrixXd& Y = pinocchio::computeJointTorqueRegressor(model, data, q(k), v(k), a(k));
      const double* x = f(&QVA[3 * n * k]);
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n_columns; ++j) err = std::max(err, std::abs(x[i + j * n] - Y(i, j)));
    }
    return err;
  };
  auto cppadcg_derivatives_error = [&](CppadcgCall& f, const std::vector<double>& X, bool forward, bool full) {
    double err = 0;
    for (long k = 0; k < n_check_derivatives; ++k) {
      const double* x = f(&X[3 * n * k]);
      const Eigen::VectorXd& ref = forward ? fd_derivatives_ref[k] : id_derivatives_ref[k];
      for (int b = 0; b < (full ? 3 : 2); ++b)
        for (int i = 0; i < n; ++i)
          for (int j = 0; j < n; ++j) {
            double got = full ? x[i * 3 * n + b * n + j] : x[b * n * n + i * n + j];
            err = std::max(err, std::abs(got - ref[n + b * n * n + j * n + i]));
          }
    }
    return err;
  };
  auto time_cppadcg = [&](CppadcgCall& f, const std::vector<double>& X) {
    return time_once([&](long k) { return f(&X[3 * n * k])[0]; }, n_samples);
  };
"""


def harness_code(n_regressor: int) -> tuple:
    """(declarations, setup, timing) C++ snippets of the harness for the generated functions.

    Inputs are packed per state as [q, v, a] and [q, v, tau] once, before timing, as CppADCodeGen's
    functions read one input vector; its Jacobians are row-major n x 3n, its derivatives three row-major
    n x n blocks.
    """
    declarations = ['extern "C" {', "struct LangCAtomicFun { void* lib_model; void* forward; void* reverse; };"]
    declarations += [
        f"void {c_function(name, kind)}(double const* const* in, double* const* out, struct LangCAtomicFun atomic);"
        for name, kind, _ in MODELS
    ]
    declarations += ["}", HELPERS]
    setup = [
        f"  const int n_regressor = {n_regressor};",
        "  std::vector<double> QVA(3 * n * n_samples), QVT(3 * n * n_samples);",
        "  for (long k = 0; k < n_samples; ++k) for (int i = 0; i < n; ++i) {",
        "    QVA[3 * n * k + i] = QVT[3 * n * k + i] = Q[k * n + i];",
        "    QVA[3 * n * k + n + i] = QVT[3 * n * k + n + i] = V[k * n + i];",
        "    QVA[3 * n * k + 2 * n + i] = A[k * n + i]; QVT[3 * n * k + 2 * n + i] = T[k * n + i];",
        "  }",
        CHECKS,
    ]
    for name, kind, size in MODELS:
        setup.append(f"  CppadcgCall cppadcg_{name}_{kind}_call({c_function(name, kind)}, {size});")
    setup += [
        '  errors["cppadcg_rnea"] = cppadcg_error(cppadcg_rnea_forward_zero_call, QVA, tau_ref, 1);',
        '  errors["cppadcg_aba"] = cppadcg_error(cppadcg_aba_forward_zero_call, QVT, qdd_ref, 1);',
        '  errors["cppadcg_regressor"] = cppadcg_regressor_error(cppadcg_regressor_forward_zero_call, n_regressor);',
        '  errors["cppadcg_rnea_jacobian"] = cppadcg_derivatives_error(cppadcg_rnea_jacobian_call, QVA, false, true);',
        '  errors["cppadcg_aba_jacobian"] = cppadcg_derivatives_error(cppadcg_aba_jacobian_call, QVT, true, true);',
        '  errors["cppadcg_rnea_derivatives"] = cppadcg_derivatives_error(cppadcg_rnea_derivatives_forward_zero_call, '
        "QVA, false, false);",
        '  errors["cppadcg_aba_derivatives"] = cppadcg_derivatives_error(cppadcg_aba_derivatives_forward_zero_call, '
        "QVT, true, false);",
    ]
    timing = []
    for name, kind, _ in MODELS:
        key = f"cppadcg_{name}" + ("_jacobian" if kind == "jacobian" else "")
        packed = "QVT" if name.startswith("aba") else "QVA"
        timing.append(f'    rounds["{key}"].push_back(time_cppadcg(cppadcg_{name}_{kind}_call, {packed}));')
    return "\n".join(declarations), "\n".join(setup), "\n".join(timing)
