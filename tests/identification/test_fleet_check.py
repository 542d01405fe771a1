"""Fleet-relative check (identification.fleet.fleet_check): healthy cells stay quiet, a clear outlier is named."""

import datetime as dt

import numpy as np

from identification.fleet.fleet_check import FleetCheckOptions, fleet_outliers
from identification.fleet.history import ParameterRow

DAYS = [dt.date(2026, 11, 1) + dt.timedelta(days=k) for k in range(12)]


def healthy_cell(rng, n_robots, joints=6, spread=0.25):
    """Robots of one model whose Coulomb and viscous friction spread by ``spread`` (manufacturing), measured daily."""
    rows = []
    for r in range(n_robots):
        for joint in range(1, joints + 1):
            for name, nominal in ((f"fc{joint}", 5.0), (f"fv{joint}", 8.0)):
                level = nominal * (1.0 + spread * rng.standard_normal())
                sigma = 0.01 * nominal
                for day in DAYS:
                    rows.append(
                        ParameterRow(f"r{r:02d}", day, name, joint, level + sigma * rng.standard_normal(), sigma)
                    )
    return rows


def test_small_healthy_cells_stay_quiet():
    # The spread of 8 robots is known only roughly: a normal-quantile threshold raised alarms on such cells.
    rng = np.random.default_rng(3)
    alarms = sum(len(fleet_outliers(healthy_cell(rng, 8))) > 0 for _ in range(40))
    assert alarms <= 2  # family-wise alpha 0.01 per cell: 40 cells, at most a couple by chance


def test_a_robot_far_outside_its_fleet_is_named():
    rng = np.random.default_rng(4)
    rows = healthy_cell(rng, 12, spread=0.05)
    worn = [ParameterRow(r.robot_id, r.day, r.name, r.joint, r.value * (3.0 if r.name == "fc2" else 1.0), r.sigma)
            if r.robot_id == "r05" else r for r in rows]  # fmt: skip
    findings = fleet_outliers(worn, FleetCheckOptions())
    assert [(f.robot_id, f.parameter, f.joint) for f in findings] == [("r05", "fc2", 2)]
    assert findings[0].size > 0
