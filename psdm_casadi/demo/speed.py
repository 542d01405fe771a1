"""The demo's C-vs-Pinocchio timing: a child process started first and collected last, and its table."""

from __future__ import annotations

import json
import subprocess
import sys

from codegen.peers.speed import SPEED_ROWS


def start_speed_job(options, workdir):
    """Start the C-vs-Pinocchio timing in a child process (it compiles Pinocchio, which takes a while)."""
    if options.speed_states <= 0:
        return None
    workdir.mkdir(parents=True, exist_ok=True)
    command = [
        sys.executable,
        "-m",
        "codegen.peers.speed",
        str(options.robot_file),
        "--workdir",
        str(workdir),
        "--samples",
        str(options.speed_states),
        "--repeats",
        "3",
        "--sum-form",
        "no",
        "--no-cppadcg",  # the demo reports the ratios against plain Pinocchio; the benchmark times the rest
    ]
    log = open(workdir / "speed.log", "w")
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=log, text=True), log


def finish_speed_job(job, timeout=900.0) -> dict:
    """The speed job's JSON result (or why there is none)."""
    if job is None:
        return {"skipped": "not measured (--quick, or speed_states=0); run benchmarks/dynamics_speed.py"}
    process, log = job
    try:
        out, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        return {"error": f"the speed run took more than {timeout:.0f} s"}
    finally:
        log.close()
    lines = out.strip().splitlines()
    try:
        return json.loads(lines[-1]) if lines else {"error": "the speed run printed nothing"}
    except json.JSONDecodeError:
        return {"error": lines[-1][:300]}


def speed_sentence(speed: dict) -> str:
    if "ns" not in speed:
        return speed.get("skipped") or speed.get("error", "not measured")
    return (
        f"inverse dynamics {speed['id_speedup_vs_pinocchio']:.2f}x Pinocchio rnea, forward dynamics "
        f"{speed['fd_speedup_vs_pinocchio']:.2f}x aba, regressor {speed['regressor_speedup_vs_pinocchio']:.2f}x"
    )


def speed_table(speed: dict) -> str:
    if "ns" not in speed:
        return "C speed: " + speed_sentence(speed)
    ns = speed["ns"]
    lines = [
        f"C speed, one C++ process, {speed['n_samples']} random states, median of {speed['repeats']} "
        "(PSDM in the recursive form with the robot file's nominal parameters baked in; -O3 -march=native):",
        "",
        "| function | PSDM [us] | Pinocchio [us] | CasADi Newton-Euler [us] | PSDM speed-up vs Pinocchio |",
        "|---|---|---|---|---|",
    ]
    for label, suffix, pin_key, peer in SPEED_ROWS:
        ours = f"psdm_{suffix}"
        peer_text = f"{ns[peer] / 1e3:.3f}" if peer else "-"
        lines.append(
            f"| {label} | {ns[ours] / 1e3:.3f} | {ns[pin_key] / 1e3:.3f} | {peer_text} | "
            f"{ns[pin_key] / ns[ours]:.2f}x |"
        )
    return "\n".join(lines)


def speed_markdown(summary) -> str:
    """``speed.md``: the speed table and the step timings (they vary from run to run)."""
    seconds = summary["seconds"]
    return "\n".join(
        [
            "# Speed and timings of this demo run",
            "",
            speed_table(summary["codegen"]["speed"]),
            "",
            "## Step timings [s]",
            "",
            "| " + " | ".join(seconds) + " |",
            "|" + "---|" * len(seconds),
            "| " + " | ".join(f"{v:.1f}" for v in seconds.values()) + " |",
            "",
        ]
    )
