"""Speed and peak memory of reading a long recording (CSV and NPZ) with ``identification.data.io.load_recording``.

Usage: python benchmarks/read_speed.py [--rows 2500000] [--joints 6] [--folder /tmp] [--compare-rev HEAD] [--json]

The file is 42 min at 1 kHz of t, q1..qn, tau1..taun (7 significant digits, about 306 MB for 6 joints),
written once into ``--folder`` and reused. Each read runs in a fresh Python process; the peak memory is
that process's peak resident set size (VmHWM, Linux) minus its size after the imports, next to the size of the arrays
read (``t``, ``q``, ``tau`` as float64). ``--compare-rev`` also times the reader of a git revision.
"""

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

# run in a child process: prints the seconds and the peak RSS growth of one load_recording call
CHILD = """
import importlib.util, json, sys, time
sys.path.insert(0, {root!r})
def high_water_mb():  # VmHWM belongs to this process image (ru_maxrss keeps the parent's peak across exec)
    with open("/proc/self/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmHWM")) / 1024
if {module!r}:
    spec = importlib.util.spec_from_file_location("reader_under_test", {module!r})
    reader = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(reader)
else:
    import identification.data.io as reader
base = high_water_mb()
start = time.perf_counter()
rec = reader.load_recording({path!r})
seconds = time.perf_counter() - start
print(json.dumps({{"seconds": seconds, "peak_mb": high_water_mb() - base, "samples": rec.n_samples}}))
"""


def write_recording_file(path: Path, n_rows: int, n_joints: int) -> None:
    """A smooth 1 kHz recording of ``n_rows`` samples, written in blocks (the writer's memory stays small)."""
    header = ",".join(["t"] + [f"q{j + 1}" for j in range(n_joints)] + [f"tau{j + 1}" for j in range(n_joints)])
    block = 200_000
    with open(path, "w") as handle:
        handle.write("# psdm recording: read-speed benchmark\n" + header + "\n")
        for start in range(0, n_rows, block):
            t = 1e-3 * np.arange(start, min(start + block, n_rows))
            phase = np.arange(1, n_joints + 1)[None, :] * t[:, None]
            data = np.hstack([t[:, None], np.sin(0.3 * phase), 20.0 * np.cos(0.7 * phase)])
            np.savetxt(handle, data, delimiter=",", fmt="%.7g")


def measure(path: Path, module: str = "") -> dict:
    code = CHILD.format(root=str(ROOT), module=module, path=str(path))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def reader_of_revision(rev: str, folder: Path) -> str:
    """The io.py of a git revision, written to ``folder`` for the child process to import."""
    text = subprocess.run(
        ["git", "show", f"{rev}:identification/data/io.py"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout
    path = folder / "io_at_revision.py"
    path.write_text(text)
    return str(path)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rows", type=int, default=2_500_000)
    parser.add_argument("--joints", type=int, default=6)
    parser.add_argument("--folder", default=tempfile.gettempdir(), help="where the generated files are kept")
    parser.add_argument("--compare-rev", default=None, help="also time the reader of this git revision")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    folder = Path(args.folder)
    csv = folder / f"psdm_read_speed_{args.rows}x{args.joints}.csv"
    if not csv.exists():
        write_recording_file(csv, args.rows, args.joints)
    npz = csv.with_suffix(".npz")
    if not npz.exists():
        sys.path.insert(0, str(ROOT))
        from identification.data.io import load_recording, save_recording

        save_recording(load_recording(csv), npz)
    array_mb = args.rows * (1 + 2 * args.joints) * 8 / 2**20
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        readers = [("working tree", "")]
        if args.compare_rev:
            readers.append((args.compare_rev, reader_of_revision(args.compare_rev, Path(scratch))))
        for label, module in readers:
            for path in (csv, npz):
                result = measure(path, module)
                size_mb = path.stat().st_size / 2**20
                rows.append({"reader": label, "file": path.name, "file_mb": size_mb, "array_mb": array_mb, **result})
    if args.json:
        print(json.dumps({"benchmark": "read_speed", "rows": rows}))
        return
    print(f"load_recording of {args.rows} samples x {args.joints} joints (t, q, tau: {array_mb:.0f} MB as float64)")
    print(f"{'reader':>14} {'file':>36} {'file [MB]':>10} {'time [s]':>9} {'peak [MB]':>10}")
    for r in rows:
        print(f"{r['reader']:>14} {r['file']:>36} {r['file_mb']:>10.0f} {r['seconds']:>9.2f} {r['peak_mb']:>10.0f}")


if __name__ == "__main__":
    main()
