"""Ctrl-C: every command stops promptly with exit 130 and leaves no partial output.

Ipopt (through CasADi) catches the KeyboardInterrupt of a Ctrl-C and ends only the running solve; the
excitation optimiser turns that into an interrupt of the whole search, and the command line repeats an
interrupt a solver swallowed until the command has ended.
"""

import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from psdm_casadi.cli.interrupts import InterruptGuard
from psdm_casadi.fileio import OutputFile, OutputFolder, atomic_write

STARTUP_TIMEOUT = 120.0  # imports and derivation on a busy machine
STOP_WITHIN = 5.0  # seconds from Ctrl-C to exit


def _interrupt_after(line_marker: str, argv, cwd, delay: float = 0.3):
    """Run ``psdm argv`` in a subprocess, send SIGINT ``delay`` s after a stderr line containing ``line_marker``.

    Returns (exit code, stderr text, seconds from SIGINT to exit).
    """
    command = [sys.executable, "-c", "import sys; from psdm_casadi.cli import main; sys.exit(main())", *argv]
    process = subprocess.Popen(command, cwd=cwd, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    lines, seen = [], threading.Event()

    def read():
        for line in process.stderr:
            lines.append(line)
            if line_marker in line:
                seen.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert seen.wait(STARTUP_TIMEOUT), "the command never reached its solver:\n" + "".join(lines)
        time.sleep(delay)
        sent = time.monotonic()
        process.send_signal(signal.SIGINT)
        code = process.wait(timeout=60)
        stopped = time.monotonic() - sent
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    reader.join(timeout=5)
    return code, "".join(lines), stopped


def test_ctrl_c_during_excite_stops_every_start_and_writes_nothing(tmp_path):
    argv = ["excite", "denso_vs6556g", "--duration", "6", "--harmonics", "3", "--starts", "5"]
    argv += ["--max-iter", "3000", "--out", "traj.csv", "--plot", "traj.png"]
    code, err, stopped = _interrupt_after("building the NLP", argv, tmp_path)
    assert code == 130, err
    assert stopped < STOP_WITHIN, f"took {stopped:.1f} s to stop:\n{err}"
    assert "interrupted" in err and "Traceback" not in err
    assert "start 2/5" not in err  # the interrupt ended the search, not only the running start
    assert os.listdir(tmp_path) == []  # no CSV, no plot, no temporary file


def test_excitation_search_raises_keyboard_interrupt(scara_functions):
    """The library: a Ctrl-C during an Ipopt start interrupts optimize_excitation itself."""
    from trajopt.optimize import ExcitationOptions, optimize_excitation

    robot, regressor = scara_functions
    options = ExcitationOptions(duration=4.0, harmonics=3, n_starts=30, max_iter=3000, quiet=True)
    timer = threading.Timer(0.8, os.kill, (os.getpid(), signal.SIGINT))
    started = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            optimize_excitation(robot, regressor, options, seed=0)
    finally:
        timer.cancel()
    assert time.monotonic() - started < 0.8 + STOP_WITHIN


@pytest.fixture(scope="module")
def scara_functions():
    from psdm_casadi import derive_psdm, load_robot
    from psdm_casadi.recursive import build_recursive_functions

    robot = load_robot("scara")
    return robot, build_recursive_functions(derive_psdm(robot), robot).regressor


def test_guard_repeats_an_interrupt_a_solver_swallowed():
    with pytest.raises(KeyboardInterrupt):
        with InterruptGuard() as guard:
            try:
                signal.raise_signal(signal.SIGINT)
            except KeyboardInterrupt:
                pass  # what CasADi's Ipopt interface does: the solve ends, the program goes on
            try:
                raise ValueError("clean-up in progress")
            except ValueError:
                time.sleep(0.3)  # no repeat while an exception is handled (the clean-up must finish)
            time.sleep(5.0)  # the repeat stops the command here
    assert guard.interrupted
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


def test_guard_without_interrupt_restores_the_handlers():
    before = signal.getsignal(signal.SIGALRM)
    with InterruptGuard() as guard:
        assert signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    assert not guard.interrupted
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.getsignal(signal.SIGALRM) is before


@pytest.mark.parametrize("existing", [False, True], ids=["new folder", "folder of an earlier run"])
def test_an_interrupted_output_folder_leaves_nothing(tmp_path, existing):
    target = tmp_path / "report"
    if existing:
        target.mkdir()
        (target / "report.md").write_text("old")
    folder = OutputFolder(target, ("report.md", "plots"))
    folder.check(force=True)
    with pytest.raises(KeyboardInterrupt):
        with folder.staging() as stage:
            (stage / "report.md").write_text("new")
            (stage / "plots").mkdir()
            (stage / "plots" / "a.png").write_bytes(b"png")
            raise KeyboardInterrupt
    assert os.listdir(tmp_path) == (["report"] if existing else [])
    if existing:
        assert os.listdir(target) == ["report.md"] and (target / "report.md").read_text() == "old"


def test_interrupted_files_leave_nothing(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with OutputFile(tmp_path / "deep" / "er" / "t.csv").staging() as path:
            path.write_text("t,q1\n")
            raise KeyboardInterrupt
    assert os.listdir(tmp_path) == []  # neither the file nor the folders made for it

    def interrupted(handle):
        handle.write("half")
        raise KeyboardInterrupt

    (tmp_path / "a.txt").write_text("old")
    with pytest.raises(KeyboardInterrupt):
        atomic_write(tmp_path / "a.txt", interrupted, overwrite=True)
    assert os.listdir(tmp_path) == ["a.txt"] and (tmp_path / "a.txt").read_text() == "old"
