"""Helpers shared by the benchmark scripts: robots used in benchmarks and table/JSON output."""

from __future__ import annotations

import json
import logging
import sysconfig
from functools import partial
from pathlib import Path

from psdm_casadi.cli.output import configure_logging
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

ROOT = Path(__file__).resolve().parents[1]
#: Where the third-party data lives (datasets/, reference/): ../shared beside the checkout, or --data-root.
DEFAULT_DATA_ROOT = ROOT.parent / "shared"
DENSO_FILE = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
PANDA_LOCKED = ("panda_finger_joint1", "panda_finger_joint2")


def example_robot_urdf(relative: str) -> Path:
    """Path of a URDF shipped by the example-robot-data wheel (cmeel prefix)."""
    for base in {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}:
        path = Path(base) / "cmeel.prefix" / "share" / "example-robot-data" / "robots" / relative
        if path.exists():
            return path
    raise FileNotFoundError(f"example-robot-data URDF {relative} not found; pip install example-robot-data")


def add_data_root_argument(parser) -> None:
    """``--data-root PATH``: the folder holding the third-party ``datasets/`` and ``reference/`` (never copied)."""
    parser.add_argument(
        "--data-root",
        type=Path,
        default=DEFAULT_DATA_ROOT,
        help=f"folder holding datasets/ and reference/ (default: ../shared beside the checkout, {DEFAULT_DATA_ROOT})",
    )


def at_data_root(path: Path, root: Path) -> Path:
    """``path`` (under :data:`DEFAULT_DATA_ROOT`) under ``root`` instead: the same dataset in another data folder."""
    return Path(root).expanduser() / Path(path).relative_to(DEFAULT_DATA_ROOT)


def loader_at(loader, folder: Path):
    """``loader`` bound to read from ``folder`` (the loaders of ``real_data_diagnosis`` take it as argument)."""
    return partial(loader, folder)


def load_panda():
    from psdm_casadi import from_urdf

    return from_urdf(example_robot_urdf("panda_description/urdf/panda.urdf"), locked_joints=PANDA_LOCKED)


def print_table(rows: list, columns: list) -> None:
    """Print a fixed-width table of dicts."""
    widths = [max(len(c), *(len(_fmt(r.get(c))) for r in rows)) for c in columns]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    print("  ".join("-" * w for w in widths))
    for row in rows:
        print("  ".join(_fmt(row.get(c)).ljust(w) for c, w in zip(columns, widths)))


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return "" if value is None else str(value)


def print_json(payload) -> None:
    print(json.dumps(payload, default=float))


def show_progress() -> None:
    """Show the libraries' progress log lines on stderr, as the ``psdm`` command does."""
    configure_logging(logging.INFO)
