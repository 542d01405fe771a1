"""identify -> diagnose --apply on the real recordings, default options only: is any joint worse at the end?

Shared by ``real_identification.py`` and ``real_data_diagnosis.py`` (key ``loop_never_worse``). For the TX40 and the
Panda (first 70 % trains, last 30 % validates, as in those benchmarks), the commands a new user would type:

    psdm identify ROBOT --data train.npz --out model.json
    psdm diagnose model.json --train train.npz --validate valid.npz --apply applied.json --json
    psdm validate model.json valid.npz --json          # and applied.json, when written

The loop holds when every joint's validation RMSE at the end (the applied model, or the identified one when the gate
refused or nothing was found) is at most its RMSE after identify plus the noise margin the diagnosis stated
(``recalibration.never_worse.margin``).
"""

from __future__ import annotations

import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

from bench_support import DEFAULT_DATA_ROOT, at_data_root, example_robot_urdf
from real_data_diagnosis import PANDA, TX40, load_panda_real, load_tx40, split

from identification.data.io import save_recording
from psdm_casadi.cli import main as psdm

PANDA_ARGV = ["--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
ROBOTS = {
    "tx40": (TX40, load_tx40, lambda folder: [str(folder / "tx40_mdh_modified.urdf")]),
    "panda": (PANDA, load_panda_real, lambda _: [str(example_robot_urdf("panda_description/urdf/panda.urdf")),
                                                 *PANDA_ARGV]),
}  # fmt: skip


def _run(argv: list) -> tuple:
    """(exit code, stdout, stderr) of one ``psdm`` command, in process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = psdm(argv)
    return code, out.getvalue(), err.getvalue()


def _validated(model: Path, valid: Path) -> list:
    code, out, err = _run(["validate", str(model), str(valid), "--json"])
    if code != 0:
        raise RuntimeError(f"psdm validate {model.name} failed ({code}): {err[-500:]}")
    return json.loads(out)["recordings"][0]["rmse"]


def run_loop(key: str, log=print, data_root: Path = DEFAULT_DATA_ROOT) -> dict:
    """The loop on one robot; ``{"skipped": True, ...}`` when its data are absent."""
    folder, loader, robot_file = ROBOTS[key]
    folder = at_data_root(folder, data_root)
    if not folder.exists():
        return {"skipped": True, "reason": f"data absent in {folder}"}
    robot, recording = loader(folder)
    robot_argv = robot_file(folder)
    train, validation = split(recording)
    result = {}
    with tempfile.TemporaryDirectory(prefix=f"psdm-loop-{key}-") as tmp:
        work = Path(tmp)
        paths = {name: work / f"{name}.npz" for name in ("train", "valid")}
        save_recording(train, paths["train"])
        save_recording(validation, paths["valid"])
        model, applied = work / "model.json", work / "applied.json"
        start = time.perf_counter()
        code, _, err = _run(["identify", *robot_argv, "--data", str(paths["train"]), "--out", str(model)])
        if code != 0:
            raise RuntimeError(f"{key}: psdm identify failed ({code}): {err[-800:]}")
        log(f"{key}: identified in {time.perf_counter() - start:.0f} s; diagnosing with --apply ...")
        argv = ["diagnose", str(model), "--train", str(paths["train"]), "--validate", str(paths["valid"]),
                "--apply", str(applied), "--json"]  # fmt: skip
        code, out, err = _run(argv)
        if code not in (0, 1):
            raise RuntimeError(f"{key}: psdm diagnose --apply failed ({code}): {err[-800:]}")
        report = json.loads(out)
        block = report.get("recalibration") or {}
        block = dict(block, **block.get("never_worse", {}))  # written: nested; refused: the block itself
        identified = _validated(model, paths["valid"])
        written = applied.exists()
        final = _validated(applied, paths["valid"]) if written else identified
        margin = block.get("margin") or [0.0] * len(identified)
        outcome = "written" if written else ("refused" if code == 1 else "nothing to apply")
        result = {
            "robot": robot.name,
            "outcome": outcome,
            "exit_code": code,
            "findings": [f["label"] for f in report.get("findings", [])],
            "kept": [e["label"] for e in json.loads(applied.read_text())["findings"]] if written else [],
            "dropped_never_worse": [d["label"] for d in block.get("dropped", [])],
            "dropped_reasons": [f"{d['label']}: {d['reason']}" for d in block.get("dropped", [])],
            "dropped_unhelpful": [d["label"] for d in block.get("dropped_findings", [])],
            "refused": block.get("refused"),
            "rmse_identify": identified,
            "rmse_end": final,
            "margin": margin,
            "diagnosis_before_model_file": report.get("model_file_rmse"),
            "preparation": report.get("preparation"),
            "nominal_model": report.get("nominal_model"),
            "seconds": time.perf_counter() - start,
        }
    result["never_worse"] = all(e <= i + m for e, i, m in zip(result["rmse_end"], result["rmse_identify"], margin))
    return result


def run_loops(keys, log=print, data_root: Path = DEFAULT_DATA_ROOT) -> dict:
    """``{"loop": {robot: result}, "loop_never_worse": bool}`` over the robots whose data are present."""
    loops = {key: run_loop(key, log, data_root) for key in keys}
    ran = [r for r in loops.values() if not r.get("skipped")]
    return {"loop": loops, "loop_never_worse": bool(ran) and all(r["never_worse"] for r in ran)}


def print_loops(loops: dict) -> None:
    """One table per robot: RMSE after identify, at the end, the margin."""
    for key, r in loops.items():
        if r.get("skipped"):
            print(f"\nloop {key}: skipped ({r['reason']})")
            continue
        print(f"\nloop {key} (identify -> diagnose --apply, defaults): {r['outcome']}; findings {r['findings']}, "
              f"kept {r['kept']}, dropped (never worse) {r['dropped_never_worse']}, dropped (no help) "
              f"{r['dropped_unhelpful']}; {r['seconds']:.0f} s")  # fmt: skip
        n = len(r["rmse_identify"])
        print("  joint           " + " ".join(f"{j + 1:>8}" for j in range(n)))
        for label, values in (("after identify", r["rmse_identify"]), ("at the end", r["rmse_end"]),
                              ("margin", r["margin"])):  # fmt: skip
            print(f"  {label:<15} " + " ".join(f"{v:8.4g}" for v in values))
        print(f"  never worse: {r['never_worse']}" + (f" (refused: {r['refused']})" if r["refused"] else ""))
        for reason in r["dropped_reasons"]:
            print(f"  dropped {reason}")
