"""What the Ipopt progress bar costs: the Panda's consistent fit with the bar drawn (a terminal) and without.

``psdm_casadi.ipopt_progress`` adds an iteration callback to the long Ipopt solves when a terminal shows the
bar. Here the Panda (Gaz et al.'s shared recording, the first 70 % as in ``real_identification.py``) is
identified with the defaults twice: once with the command line's ``ProgressHandler`` on a stream that says it is
a terminal (the bar drawn into memory), once without (no callback). Reported: the consistent fit's Ipopt
iterations, the time spent inside the callback against the solves' time (``callback_fraction``, target < 0.05),
and the whole fit's process CPU time both ways (its difference includes CasADi's cost of calling the callback,
but also the machine's noise).

Usage::

    python benchmarks/ipopt_progress.py [--json] [--data-root PATH]
"""

from __future__ import annotations

import argparse
import io
import json
import logging
import sys
import time

from bench_support import DEFAULT_DATA_ROOT, add_data_root_argument, at_data_root
from real_data_diagnosis import PANDA, load_panda_real, split

import identification.calibration.consistent_fit as consistent_fit
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from psdm_casadi.cli.output import ProgressHandler
from psdm_casadi.model_cache import ModelCache

TARGET = 0.05


class _Terminal(io.StringIO):
    def isatty(self):
        return True


class _Timed:
    """``progress_options`` of the consistent fit, noting each solve's callback and its time."""

    def __init__(self, original):
        self.original, self.solves = original, []

    def __call__(self, *args, **kwargs):
        options, callback = self.original(*args, **kwargs)
        if callback is not None:
            close = callback.close
            started = time.perf_counter()

            def timed_close():
                self.solves.append((callback.iterations, callback.seconds, time.perf_counter() - started))
                close()

            callback.close = timed_close
        return options, callback


def _fit(robot, model, train, bar: bool) -> float:
    """Process CPU seconds of one identification with the defaults, the bar drawn or not."""
    parent = logging.getLogger("identification")
    saved = (parent.handlers[:], parent.level, parent.propagate)
    if bar:
        parent.handlers[:] = [ProgressHandler(_Terminal())]
        parent.setLevel(logging.INFO)
        parent.propagate = False
    try:
        start = time.process_time()
        identify_trajectories(robot, model, [train], TrajectoryOptions())
        return time.process_time() - start
    finally:
        parent.handlers[:], parent.level, parent.propagate = saved


def evaluate(data) -> dict:
    robot, recording = load_panda_real(data)
    train, _ = split(recording)
    model = ModelCache().derive(robot)
    timed = _Timed(consistent_fit.progress_options)
    consistent_fit.progress_options = timed
    try:
        without = _fit(robot, model, train, bar=False)
        with_bar = _fit(robot, model, train, bar=True)
    finally:
        consistent_fit.progress_options = timed.original
    iterations = sum(s[0] for s in timed.solves)
    inside, solving = sum(s[1] for s in timed.solves), sum(s[2] for s in timed.solves)
    return {"solves": len(timed.solves), "iterations": iterations, "callback_seconds": inside,
            "solve_seconds": solving, "callback_fraction": inside / max(solving, 1e-12),
            "callback_ms_per_iteration": 1e3 * inside / max(iterations, 1),
            "fit_cpu_seconds_without_bar": without, "fit_cpu_seconds_with_bar": with_bar,
            "target_fraction": TARGET}  # fmt: skip


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    add_data_root_argument(parser)
    args = parser.parse_args(argv)
    data = at_data_root(PANDA, args.data_root if args.data_root else DEFAULT_DATA_ROOT)
    if not data.exists():
        print(f"skipped: Panda data absent in {data}", file=sys.stderr)
        return 2
    result = evaluate(data)
    if args.json:
        print(json.dumps({"ipopt_progress": result}))
    else:
        print("Panda consistent fit (defaults), Ipopt progress bar drawn on a terminal:")
        for key, value in result.items():
            print(f"  {key:<30} {value:.4g}" if isinstance(value, float) else f"  {key:<30} {value}")
    return 0 if result["callback_fraction"] < TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
