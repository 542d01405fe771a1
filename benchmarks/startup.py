"""Start-up time of a ``psdm`` command on the Panda: cold (model derived) and warm (model read from the cache).

Each run is a fresh ``psdm derive`` subprocess on the example-robot-data Panda with its fingers locked, with an
empty model cache (``PSDM_CACHE_DIR`` = a temporary folder) for the cold run and the filled one for the warm runs;
``import`` is the interpreter start and import of the ``psdm`` command alone. Target: warm start under 2 s.

Usage: python benchmarks/startup.py [--json] [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

from bench_support import PANDA_LOCKED, ROOT, example_robot_urdf, print_json, print_table

TARGET_WARM_S = 2.0
PSDM = "import sys; from psdm_casadi.cli import main; sys.exit(main())"


def timed(command: list, env: dict) -> float:
    """Wall seconds of one subprocess run (which must succeed)."""
    start = time.perf_counter()
    subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--repeats", type=int, default=3, help="warm runs; the median is reported")
    args = parser.parse_args(argv)
    urdf = example_robot_urdf("panda_description/urdf/panda.urdf")
    locks = [arg for name in PANDA_LOCKED for arg in ("--lock", name)]
    derive = [sys.executable, "-c", PSDM, "derive", str(urdf), *locks]
    with tempfile.TemporaryDirectory(prefix="psdm-startup-") as folder:
        env = {**os.environ, "PSDM_CACHE_DIR": folder, "PYTHONPATH": str(ROOT)}
        imports = timed([sys.executable, "-c", "import psdm_casadi.cli"], env)
        cold = timed(derive, env)
        warm = sorted(timed(derive, env) for _ in range(max(args.repeats, 1)))[max(args.repeats, 1) // 2]
    rows = [
        {"run": "import psdm_casadi.cli", "seconds": imports},
        {"run": "psdm derive panda (cold: derived)", "seconds": cold},
        {"run": "psdm derive panda (warm: cache)", "seconds": warm, "target_s": TARGET_WARM_S},
    ]
    ok = warm <= TARGET_WARM_S
    if args.json:
        print_json({"runs": rows, "cold_s": cold, "warm_s": warm, "speedup": cold / warm, "all_targets_met": ok})
    else:
        print_table(rows, ["run", "seconds", "target_s"])
        print(f"speed-up {cold / warm:.1f}x; " + ("all targets met" if ok else "SOME TARGETS MISSED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
