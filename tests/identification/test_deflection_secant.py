"""A deflection screened at the size of least exact training error (``BacklashTerm.shape_variants``,
``JointElasticityTerm.shape_variants``).

The friction part of a deflection's column is the change of the robot file's LuGre friction when the velocity is
shifted by the deflection's rate: far from linear in the deflection, so the column is a secant at a size, nominally
0.1 deg of half-play (0.2 deg of torsion at the RMS torque). Given a ``JointScore`` the terms offer, beside that, the
secant at the size whose exact contribution fits the training recording best (the log grid's parabola,
``deflection.fitted_secant``). The diagnosis benchmark's backlash at seeds 1-2 (0.43 and 0.30 deg of play) lost to
the friction shapes with the nominal secant and is named with it (``test_diagnosis_benchmark_scenarios``).
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.diagnosis.candidates import BacklashTerm, JointElasticityTerm
from identification.diagnosis.candidates.deflection import SCAN_POINTS, fitted_secant
from identification.diagnosis.term_spec import term_from_spec
from psdm_casadi.errors import ParameterError


def test_the_fitted_secant_is_the_vertex_of_the_profile_on_the_log_grid():
    """A profile quadratic in log(size) with its minimum at 2.7 times the nominal: the grid's best point and its
    neighbours' parabola give the minimum exactly; one at the nominal size or below gives None (the nominal stands);
    the grid ends at the bound ``upper``."""
    seen = []

    def profile(size, centre):
        seen.append(size)
        return 1.0 + (np.log(size) - np.log(centre)) ** 2

    nominal = 0.002
    assert fitted_secant(lambda s: profile(s, 2.7 * nominal), nominal, 1.0) == pytest.approx(2.7 * nominal, rel=1e-9)
    assert len(seen) == SCAN_POINTS and min(seen) == pytest.approx(nominal) and max(seen) == pytest.approx(10 * nominal)
    assert fitted_secant(lambda s: profile(s, 1.05 * nominal), nominal, 1.0) is None
    assert fitted_secant(lambda s: profile(s, 0.1 * nominal), nominal, 1.0) is None  # never below the nominal
    seen.clear()
    fitted_secant(lambda s: profile(s, nominal), nominal, 3 * nominal)
    assert max(seen) == pytest.approx(3 * nominal)


def test_without_a_score_a_deflection_is_screened_at_its_nominal_secant():
    for term in (BacklashTerm(joint=4), JointElasticityTerm(joint=4)):
        assert term.shape_variants(None) == (term,) and term.n_shape_parameters == 0
        assert term.shape_variants(None, None)[0].secant is None


def test_the_secant_is_stored_by_its_definition_and_counts_as_a_shape_parameter():
    """A model file stores a kept deflection by its spec: the secant comes back; a spec without it (files written
    before) gives the nominal secant."""
    for term in (BacklashTerm(joint=2, secant=0.003), JointElasticityTerm(joint=2, secant=1e-4)):
        assert term_from_spec(term.spec()) == term and term.spec()["secant"] == term.secant
        assert term.n_shape_parameters == 1 and term.label == type(term)(joint=2).label
    assert term_from_spec({"key": "backlash", "joint": 2}) == BacklashTerm(joint=2)


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan"), "0.01", True])
def test_a_secant_that_is_no_size_is_refused(bad):
    for kind in (BacklashTerm, JointElasticityTerm):
        with pytest.raises(ParameterError, match=f"{kind.__name__}.secant"):
            kind(joint=1, secant=bad)
