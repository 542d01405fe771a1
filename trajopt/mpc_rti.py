"""Real-time-iteration NMPC: one Gauss-Newton SQP step per control interval as one compiled CasADi Function.

The tracking problem is the one of ``trajopt.mpc`` (same cost, bounds, RK4 model); instead of
iterating an NLP solver from Python, each control interval takes exactly one SQP step from the
shifted previous solution (the real-time iteration of Diehl et al., the scheme of acados): the
stage models and their Jacobians at the guess, the constant Gauss-Newton Hessian of the
least-squares cost, and the structured QP in the step ``dw`` solved by HPIPM (Riccati-based
interior point, through CasADi's ``conic`` plugin). Everything, the shift for the next interval
included, is one Function ``mpc_rti(x0, w, p) -> (u, w_next, w_sol)``; ``export_rti_c`` writes it as
C (with the dynamics and their derivatives inlined), ``compile_rti`` builds and loads it, so the
per-step loop holds no Python: a C program calls ``mpc_rti`` directly (see ``examples/`` in the
report of ``benchmarks/mpc.py``), Python calls the same compiled code through ``casadi.external``.
"""

from __future__ import annotations

import dataclasses
import logging
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import ParameterError, SolverError
from trajopt.c_compiler import run_compiler
from trajopt.hpipm_c import hpipm_folders, persistent_workspace
from trajopt.joint_friction import friction_function
from trajopt.mpc import MPCOptions, constraint_jacobian, step_arguments, tracking_cost, variable_bounds
from trajopt.mpc_model import expanded, stage_functions
from trajopt.riccati_qp import RiccatiQP, riccati_qp

LOG = logging.getLogger(__name__)
RTI_NAME = "mpc_rti"
QP_SOURCE = "riccati_qp.c"
# HPIPM's own presets: "speed_abs" (no residual checks), "speed", "balance", "robust"
QP_MODES = ("speed_abs", "speed", "balance", "robust")
# the QP of a step: this package's Riccati solver in C (trajopt.riccati_qp) or HPIPM through CasADi
RTI_QP_SOLVERS = ("riccati", "hpipm")
# CasADi's generated HPIPM call fails the whole Function on any status but success (its error_on_fail is
# not honoured in generated code), also at the iteration cap, whose iterate the real-time scheme applies
# (as the MX Function does with error_on_fail=False); the export takes the check out, and the caller
# still rejects non-finite results
QP_FAILURE_CHECK = "\n  if (d.return_status!=0) {\n    return -1;\n  }\n"


@dataclass
class RTIController:
    """A real-time-iteration MPC: the step Function and the guess it carries from one interval to the next.

    Attributes
    ----------
    function : casadi.Function
        ``(x0, w, p) -> (u, w_next, w_sol)``: measured state (2 n_dof,), guess (stage order
        x0, u0, ..., x_N), reference (2 n_dof (N + 1),) column-major -> first torque, the shifted
        solution (next interval's guess) and the solution itself. The MX Function (evaluated by
        CasADi's virtual machine) or its compiled twin from ``compile_rti``.
    options : MPCOptions
        Horizon, interval, RK4 steps and weights; ``max_iter`` and ``tol`` are HPIPM's cap and tolerance.
    n_dof : int
    bounds : dict
        ``lbx``, ``ubx`` of the variables (the same as ``trajopt.mpc``'s).
    prediction : casadi.Function, optional
        ``(x, u) -> x_next``: the controller's model over one interval (the integrator on the forward
        dynamics, friction included), the Function whose Jacobian the QP's linearisation holds.
    qp : RiccatiQP, optional
        The QP solver the step calls when it is this package's (its C is compiled with the step's).
    """

    function: ca.Function
    options: MPCOptions
    n_dof: int
    bounds: dict
    prediction: ca.Function | None = None
    qp: RiccatiQP | None = None
    _guess: np.ndarray | None = field(default=None, repr=False)
    _buffers: tuple | None = field(default=None, repr=False)

    def initialize(self, states, torques) -> None:
        """Set the first guess: states (N + 1, 2 n_dof) and torques (N, n_dof)."""
        states, torques = np.asarray(states, dtype=float), np.asarray(torques, dtype=float)
        n, horizon = self.n_dof, self.options.horizon
        if states.shape != (horizon + 1, 2 * n) or torques.shape != (horizon, n):
            raise ParameterError(
                f"RTIController.initialize needs states ({horizon + 1}, {2 * n}) and torques ({horizon}, {n}); "
                f"got {states.shape} and {torques.shape}."
            )
        self._guess = np.concatenate([np.hstack([states[:-1], torques]).ravel(), states[-1]])

    def warm_up(self, state, reference, iterations: int) -> None:
        """Take ``iterations`` RTI steps from the same state without shifting: the converged start of a
        real-time loop (the first guess is usually far from optimal)."""
        for _ in range(iterations):
            _, _, w, _ = self.function(state, self._guess, np.asarray(reference, dtype=float).ravel())
            self._guess = np.asarray(w).ravel()

    def step(self, state, reference) -> tuple[np.ndarray, dict]:
        """One real-time iteration: returns the first torque (n_dof,) and the step's timing.

        ``reference`` is (N + 1, 2 n_dof): (q_ref, qd_ref) at the N + 1 nodes from now. The solution,
        shifted by one interval, is the next step's guess.

        Raises
        ------
        ParameterError
            On a state or reference of the wrong shape, or before ``initialize``.
        SolverError
            When the QP returns non-finite numbers.
        """
        state, reference = step_arguments(
            "RTIController", self.n_dof, self.options.horizon, state, reference, self._guess
        )
        _, trigger, inputs, outputs = self._buffers or self._make_buffers()
        inputs[0][:], inputs[1][:], inputs[2][:] = state, self._guess, reference.ravel()
        start, start_cpu = time.perf_counter(), time.process_time()
        trigger()
        elapsed, cpu = time.perf_counter() - start, time.process_time() - start_cpu
        u, w_next = outputs[0].copy(), outputs[1].copy()
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(w_next))):
            raise SolverError(
                "MPC real-time iteration: the QP returned non-finite values; check the state against the "
                "limits and the reference, or warm up from a better guess.",
                status="non-finite",
            )
        self._guess = w_next
        stats = {"time_s": elapsed, "cpu_time_s": cpu, "iter_count": 1, "return_status": "rti"}
        return u, stats

    def _make_buffers(self) -> tuple:
        """CasADi's zero-copy call (``Function.buffer``): numpy arrays bound to the inputs and outputs
        once, so a step is the compiled code alone, not CasADi's conversion of Python arguments."""
        buffer, trigger = self.function.buffer()
        inputs = [np.zeros(self.function.nnz_in(i)) for i in range(self.function.n_in())]
        outputs = [np.zeros(self.function.nnz_out(i)) for i in range(self.function.n_out())]
        for i, array in enumerate(inputs):
            buffer.set_arg(i, memoryview(array))
        for i, array in enumerate(outputs):
            buffer.set_res(i, memoryview(array))
        self._buffers = (buffer, trigger, inputs, outputs)
        return self._buffers


def build_rti(
    robot: RobotDescription,
    forward_dynamics: ca.Function,
    options: MPCOptions | None = None,
    *,
    friction=True,
    forward_dynamics_jacobian: ca.Function | None = None,
    qp_mode: str = "speed_abs",
    qp_solver: str = "riccati",
) -> RTIController:
    """Build the real-time-iteration MPC of a robot on a forward-dynamics function (not compiled yet).

    Parameters
    ----------
    robot : RobotDescription
        Gives the joint position, velocity and torque limits and (``friction=True``) the drives.
    forward_dynamics : casadi.Function
        ``(q, qd, tau) -> qdd`` of the controller's model (SX or MX; an external's C is linked when compiled).
    options : MPCOptions, optional
        The horizon, interval, RK4 steps and weights of ``trajopt.mpc``; ``max_iter`` caps HPIPM's
        interior-point iterations and ``tol`` is its tolerance (the solver, Hessian and jit fields do not apply).
    friction : bool
        Subtract the drives' smooth friction from the torque before the dynamics.
    forward_dynamics_jacobian : casadi.Function, optional
        ``(q, qd, tau) -> (d qdd/d q, d qdd/d qd, d qdd/d tau)``, e.g.
        ``trajopt.mpc_model.build_forward_dynamics_jacobian`` (through the inverse dynamics); CasADi's
        AD of forward_dynamics otherwise.
    qp_mode : {"speed_abs", "speed", "balance", "robust"}
        HPIPM's preset; "speed_abs" (the default) skips the residual checks of each interior-point
        iteration and stops at ``options.max_iter`` (4 in benchmarks/mpc.py: the real-time scheme
        applies an inexact QP step, corrected at the next interval), the others stop at ``options.tol``.
    qp_solver : {"riccati", "hpipm"}
        The QP's solver: "riccati" (the default), this package's C for the stage structure
        (``trajopt.riccati_qp``: the exact solution by one Riccati recursion when no bound is active,
        else an interior point stopping at ``options.tol`` or ``options.max_iter``; compiled with the C
        compiler on first use), or HPIPM through CasADi (with ``qp_mode``; CasADi's portable BLASFEO
        unless ``make hpipm`` built one for the CPU).

    Returns
    -------
    RTIController
        Call ``compile_rti`` for the C speed, then ``initialize`` and ``step`` once per interval.

    Raises
    ------
    ParameterError
        When forward_dynamics does not map three (n_dof,) inputs to one (n_dof,) output, or on an unknown qp_mode.
    """
    options = options or MPCOptions()
    n = robot.n_dof
    if forward_dynamics.n_in() != 3 or any(forward_dynamics.size_in(i) != (n, 1) for i in range(3)):
        raise ParameterError(
            f"build_rti forward_dynamics must take (q, qd, tau) of shape ({n}, 1) each for {robot.name}; "
            f"got inputs {[forward_dynamics.size_in(i) for i in range(forward_dynamics.n_in())]}."
        )
    if qp_mode not in QP_MODES:
        raise ParameterError(f"build_rti qp_mode must be one of {QP_MODES}; got {qp_mode!r}.")
    if qp_solver not in RTI_QP_SOLVERS:
        raise ParameterError(f"build_rti qp_solver must be one of {RTI_QP_SOLVERS}; got {qp_solver!r}.")
    friction_law = friction_function(robot) if friction else None
    _, model_jacobian = stage_functions(
        expanded(forward_dynamics),
        n,
        options.dt,
        options.rk4_steps,
        friction_law,
        forward_dynamics_jacobian,
        options.integrator,
    )
    bounds = variable_bounds(robot, options.horizon)
    qp = None
    if qp_solver == "riccati":
        qp = riccati_qp(2 * n, n, options.horizon, options.max_iter, options.tol)
        function = riccati_rti_function(robot, options, model_jacobian, bounds, qp)
    else:
        function = rti_function(robot, options, model_jacobian, bounds, qp_mode)
    x, u = ca.MX.sym("x", 2 * n), ca.MX.sym("u", n)
    prediction = ca.Function("prediction", [x, u], [model_jacobian(x, u)[0]], ["x", "u"], ["x_next"])
    return RTIController(function, options, n, bounds, prediction, qp)


def riccati_rti_function(robot, options, model_jacobian, bounds, qp: RiccatiQP) -> ca.Function:
    """``(x0, w, p) -> (u, w_next, w_sol, lam_g)`` as ``rti_function``, the QP by ``trajopt.riccati_qp``:
    the stage Jacobians go to it as they come from the model (dense blocks), the Hessian as its diagonal."""
    n, horizon = robot.n_dof, options.horizon
    n_w = 3 * n * horizon + 2 * n
    x0, w, p = ca.MX.sym("x0", 2 * n), ca.MX.sym("w", n_w), ca.MX.sym("p", 2 * n * (horizon + 1))
    pieces = qp_pieces(robot, options, model_jacobian, bounds, x0, w, p)
    hessian = pieces["hessian"]
    if hessian.nnz() != n_w or ca.triu(hessian, False).nnz() > 0:
        raise SolverError("riccati_rti_function: the tracking cost's Hessian must be diagonal", status="structure")
    step, lam_g = qp.function(
        ca.diag(hessian), pieces["g"], pieces["blocks"], -pieces["gaps"], pieces["lbx"], pieces["ubx"]
    )
    # held inside the bounds in absolute terms too: w + (ubx - w) can round above ubx by an ulp
    solution = ca.fmin(ca.fmax(w + step, pieces["low"]), pieces["high"])
    return ca.Function(
        RTI_NAME,
        [x0, w, p],
        [solution[2 * n : 3 * n], shift_guess(solution, n), solution, lam_g],
        ["x0", "w", "p"],
        ["u", "w_next", "w_sol", "lam_g"],
    )


def qp_pieces(robot, options, model_jacobian, bounds, x0, w, p) -> dict:
    """The Gauss-Newton QP of one SQP step from w (see ``rti_qp_data``) as expressions in (x0, w, p): the
    constant Hessian (DM, every diagonal entry present), gradient, stage Jacobians ``[A_k B_k]`` side by
    side, gaps ``x_{k+1} - F(x_k, u_k)``, the constraint Jacobian, the bounds of the step and of the variables."""
    n, horizon = robot.n_dof, options.horizon
    n_w = w.numel()
    states = ca.horzcat(*[w[3 * n * k : 3 * n * k + 2 * n] for k in range(horizon + 1)])
    torques = ca.horzcat(*[w[3 * n * k + 2 * n : 3 * n * (k + 1)] for k in range(horizon)])
    values, blocks = model_jacobian.map(horizon)(states[:, :-1], torques)
    cost = tracking_cost(robot, options, states, torques, p)
    hessian = ca.Function("h", [w, p], [ca.hessian(cost, w)[0]])(np.zeros(n_w), np.zeros(p.numel()))
    hessian = ca.DM(ca.sparsify(hessian)) + ca.DM(ca.Sparsity.diag(n_w), 0.0)
    lbx, ubx = ca.DM(bounds["lbx"]), ca.DM(bounds["ubx"])
    lbx[: 2 * n] = ubx[: 2 * n] = 0
    measured = ca.vertcat(x0, ca.MX(n_w - 2 * n, 1))
    return {
        "hessian": hessian,
        "g": ca.gradient(cost, w),
        "blocks": blocks,
        "gaps": ca.vec(states[:, 1:] - values),
        "jac_g": constraint_jacobian(w, states, torques, model_jacobian, n),
        "lbx": measured + lbx - w,
        "ubx": measured + ubx - w,
        "low": measured + lbx,
        "high": measured + ubx,
    }


def rti_function(robot, options, model_jacobian, bounds, qp_mode="speed") -> ca.Function:
    """``(x0, w, p) -> (u, w_next, w_sol, lam_g)``: one Gauss-Newton SQP step from w with HPIPM, and its shift.

    The QP (``rti_qp_data``) is in the step ``dw``; lam_g are its gap multipliers (an output because
    the plugin writes them unconditionally).
    """
    n, horizon = robot.n_dof, options.horizon
    n_w = 3 * n * horizon + 2 * n
    x0, w, p = ca.MX.sym("x0", 2 * n), ca.MX.sym("w", n_w), ca.MX.sym("p", 2 * n * (horizon + 1))
    data = rti_qp_data(robot, options, model_jacobian, bounds)
    qp = rti_qp_solver(data, options, qp_mode)
    args = data(x0=x0, w=w, p=p)
    zeros = ca.MX(n_w, 1)  # every input given: the plugin reads the initial guesses unconditionally
    step = qp(**{k: args[k] for k in ("h", "g", "a", "lba", "uba", "lbx", "ubx")}, x0=zeros, lam_x0=zeros,
              lam_a0=ca.MX(data.size1_out("a"), 1))  # fmt: skip
    solution = w + step["x"]
    return ca.Function(
        RTI_NAME,
        [x0, w, p],
        [solution[2 * n : 3 * n], shift_guess(solution, n), solution, step["lam_a"]],
        ["x0", "w", "p"],
        ["u", "w_next", "w_sol", "lam_g"],
    )


def rti_qp_data(robot, options, model_jacobian, bounds) -> ca.Function:
    """``(x0, w, p) -> (h, g, a, lba, uba, lbx, ubx)``: the Gauss-Newton QP of one SQP step from w.

    ``min 1/2 dw' H dw + g' dw`` subject to the linearised gaps ``a dw = -gaps(w)`` (lba = uba), the
    variable bounds shifted by w and ``dx0 = x0 - w_x0`` (equal bounds on the first state). H is the
    cost's constant Hessian (a least-squares cost: Gauss-Newton is exact for it) with every diagonal
    entry present, as HPIPM's block detection wants.
    """
    n, horizon = robot.n_dof, options.horizon
    n_w = 3 * n * horizon + 2 * n
    x0, w, p = ca.MX.sym("x0", 2 * n), ca.MX.sym("w", n_w), ca.MX.sym("p", 2 * n * (horizon + 1))
    q = qp_pieces(robot, options, model_jacobian, bounds, x0, w, p)
    return ca.Function(
        "rti_qp_data",
        [x0, w, p],
        [ca.MX(q["hessian"]), q["g"], q["jac_g"], -q["gaps"], -q["gaps"], q["lbx"], q["ubx"]],
        ["x0", "w", "p"],
        ["h", "g", "a", "lba", "uba", "lbx", "ubx"],
    )


def rti_qp_solver(data: ca.Function, options: MPCOptions, qp_mode: str) -> ca.Function:
    """HPIPM through CasADi's conic on the QP of ``rti_qp_data`` (stage structure detected from the sparsity)."""
    hpipm = {"mode": qp_mode, "iter_max": options.max_iter}
    hpipm.update({key: options.tol for key in ("res_g_max", "res_b_max", "res_d_max", "res_m_max")})
    return ca.conic(
        "rti_qp",
        "hpipm",
        {"h": data.sparsity_out("h"), "a": data.sparsity_out("a")},
        {"error_on_fail": False, "print_time": False, "hpipm": hpipm},
    )


def shift_guess(w, n_dof):
    """Shift a solution (x0, u0, ..., x_N) by one interval: (x1, u1, ..., x_N, u_{N-1}, x_N)."""
    stage, tail = 3 * n_dof, 2 * n_dof
    n_w = w.shape[0]
    return ca.vertcat(w[stage:], w[n_w - tail - n_dof : n_w - tail], w[n_w - tail :])


def export_rti_c(controller: RTIController, folder) -> Path:
    """Write the RTI step as C: ``<folder>/mpc_rti.c`` and ``mpc_rti.h``; returns the source path.

    With the Riccati QP (the default) the step calls ``<folder>/riccati_qp.c``, written beside it:
    compile the two together (``cc -O3 -march=native mpc_rti.c riccati_qp.c -lm``). With HPIPM the C
    calls HPIPM (``hpipm_d_ocp_qp_ipm.h``), shipped with CasADi: compile with ``-I<casadi>/include
    -L<casadi> -lhpipm -lblasfeo``; HPIPM's workspace is created on the first call and kept
    (``trajopt.hpipm_c.persistent_workspace``). ``compile_rti`` does either. One thread at a time calls the step.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    source = folder / f"{RTI_NAME}.c"
    generator = ca.CodeGenerator(source.name, {"with_header": True})
    generator.add(controller.function)
    generator.generate(str(folder) + "/")
    if controller.qp is not None:
        (folder / QP_SOURCE).write_text(controller.qp.source)
        return source
    text = source.read_text()
    if QP_FAILURE_CHECK not in text:
        raise SolverError(
            f"export_rti_c: CasADi {ca.__version__} generated the HPIPM call differently than expected; the "
            "iteration cap of the real-time scheme would fail the step. Check the generated code.",
            status="codegen",
        )
    text = text.replace(QP_FAILURE_CHECK, "\n  /* RTI: an iterate at HPIPM's cap is applied */\n")
    source.write_text(persistent_workspace(text))
    return source


def compile_rti(
    controller: RTIController, folder, *, compiler="cc", flags=("-O3", "-march=native"), hpipm_dir=None
) -> RTIController:
    """Export, compile and load the RTI step; returns a controller whose ``function`` is the compiled C.

    ``hpipm_dir``: see ``hpipm_folders`` (CasADi's HPIPM and BLASFEO by default; HPIPM path only).

    Raises
    ------
    SolverError
        When the compiler is missing or fails (its last lines quoted).
    """
    source = export_rti_c(controller, folder)
    library = Path(folder) / f"lib{RTI_NAME}.so"
    found = shutil.which(compiler)
    if found is None:
        raise SolverError(f"compile_rti compiler must be on PATH; {compiler!r} was not found. Install gcc or pass one.")
    if controller.qp is not None:
        command = [found, *flags, "-fPIC", "-shared", "-o", str(library), str(source), str(Path(folder) / QP_SOURCE)]
        return _compiled(controller, command + ["-Wl,-Bsymbolic", "-lm"], library)
    include, lib = hpipm_folders(hpipm_dir)
    if (lib / "libhpipm.a").exists() and (lib / "libblasfeo.a").exists():
        # linked in: a process that already loaded CasADi's libhpipm.so (its conic plugin) would
        # otherwise bind the shared libraries of that name to CasADi's copies
        libraries = [str(lib / "libhpipm.a"), str(lib / "libblasfeo.a"), "-Wl,-Bsymbolic"]
    else:
        libraries = [f"-L{lib}", "-lhpipm", "-lblasfeo", "-Wl,--disable-new-dtags", f"-Wl,-rpath,{lib}"]
    command = [found, *flags, "-fPIC", "-shared", "-o", str(library), str(source), f"-I{include}", *libraries, "-lm"]
    return _compiled(controller, command, library)


def _compiled(controller: RTIController, command: list, library: Path) -> RTIController:
    """Run the compiler command and load the step from the library it writes."""
    start = time.perf_counter()
    run_compiler(command, "compile_rti's step")
    LOG.info("compiled %s in %.1f s", library, time.perf_counter() - start)
    compiled = ca.external(RTI_NAME, str(library))
    return dataclasses.replace(controller, function=compiled, _guess=None, _buffers=None)
