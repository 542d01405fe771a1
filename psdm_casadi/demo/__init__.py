"""psdm demo: the whole discovery loop on the built-in virtual Denso, from robot file to compiled C and a report.

derive -> optimise excitation -> simulate the calibration experiments on a virtual robot that
carries a hidden cable-harness spring on joint 4 -> identify in the paper's four steps (the spring
corrupts them: shown) -> diagnose the hidden effect -> identify again with the spring as a known
term -> export and compile C of the corrected model (rigid body, friction and spring) -> report folder.

With the command line, this package is the one place that composes every package (each step
imports the package it needs); no library module imports it. Modules: ``options`` (sizes and the
run state), ``story`` (the steps), ``speed`` (the Pinocchio timing job), ``markdown`` (the report),
``command`` (``psdm demo``).
"""

from psdm_casadi.demo.command import register
from psdm_casadi.demo.options import DENSO_FILE, REPORT_ENTRIES, REPORT_FORMAT, DemoOptions, DemoResult
from psdm_casadi.demo.story import run_demo

__all__ = ["DENSO_FILE", "REPORT_ENTRIES", "REPORT_FORMAT", "DemoOptions", "DemoResult", "register", "run_demo"]
