"""The inlined sin/cos of the exported C (codegen/templates/fast_trig.c.in) against numpy, and their use by export_c."""

import ctypes
import re
import shutil

import casadi as ca
import numpy as np
import pytest

from codegen.build import compile_shared
from codegen.export import export_c

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
TEMPLATE_NAME = "fast_trig.c.in"


@pytest.fixture(scope="module")
def fast_trig(tmp_path_factory):
    """ctypes access to psdm_sin/psdm_cos compiled at -O2 from the template."""
    from codegen.export import _template

    folder = tmp_path_factory.mktemp("fast_trig")
    source = folder / "trig.c"
    source.write_text(
        "#include <math.h>\n"
        + _template(TEMPLATE_NAME)
        + """
void evaluate(const double* x, double* s, double* c, int n) {
  for (int i = 0; i < n; ++i) { s[i] = psdm_sin(x[i]); c[i] = psdm_cos(x[i]); }
}
void evaluate_n(const double* x, double* s, double* c, int n) { psdm_sincos_n(x, s, c, n); }
"""
    )
    library = ctypes.CDLL(str(compile_shared([source], folder / "libtrig.so", flags=("-O2",))))
    pointer = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    library.evaluate.argtypes = library.evaluate_n.argtypes = [pointer, pointer, pointer, ctypes.c_int]

    def evaluate(x):
        """(sin, cos) by psdm_sin/psdm_cos, after checking psdm_sincos_n gives the same bits."""
        x = np.ascontiguousarray(x, dtype=float)
        s, c, s_n, c_n = (np.empty_like(x) for _ in range(4))
        library.evaluate(x, s, c, x.size)
        library.evaluate_n(x, s_n, c_n, x.size)
        np.testing.assert_array_equal(s_n, s)
        np.testing.assert_array_equal(c_n, c)
        return s, c

    return evaluate


@pytest.mark.needs_cc
@needs_cc
def test_fast_sin_cos_within_a_few_ulp_of_numpy(fast_trig):
    rng = np.random.default_rng(0)
    quadrant_edges = np.pi / 4 * np.arange(-400, 401)
    x = np.concatenate(
        [
            rng.uniform(-np.pi, np.pi, 200_000),  # joint angles
            rng.uniform(-1e4, 1e4, 50_000),  # many turns of a continuous joint
            np.nextafter(quadrant_edges, np.inf),
            np.nextafter(quadrant_edges, -np.inf),  # reduction boundaries
            np.pi / 2 * np.arange(-1000, 1001),  # near the zeros of sin and cos
            [0.0, -0.0, 1e-300, -1e-300, 99_999.9, np.nextafter(2.0**17, 0.0)],  # up to the libm limit 2^17
        ]
    )
    s, c = fast_trig(x)
    # absolute error: a few ulp of 1 (the functions are bounded by 1)
    assert np.abs(s - np.sin(x)).max() <= 4 * np.finfo(float).eps
    assert np.abs(c - np.cos(x)).max() <= 4 * np.finfo(float).eps
    small = np.abs(x) < 1e-3  # and relative accuracy where sin(x) ~ x
    np.testing.assert_allclose(s[small], np.sin(x[small]), rtol=4 * np.finfo(float).eps, atol=0)


@pytest.mark.needs_cc
@needs_cc
def test_fast_sin_cos_hand_large_and_non_finite_arguments_to_libm(fast_trig):
    x = np.array([2.0**17, -(2.0**17), 3.7e7, -1e300, np.inf, -np.inf, np.nan])
    s, c = fast_trig(x)
    finite = np.isfinite(x)
    np.testing.assert_allclose(s[finite], np.sin(x[finite]), rtol=0, atol=4 * np.finfo(float).eps)
    np.testing.assert_allclose(c[finite], np.cos(x[finite]), rtol=0, atol=4 * np.finfo(float).eps)
    assert np.all(np.isnan(s[~finite])) and np.all(np.isnan(c[~finite]))


def test_export_replaces_libm_trig_unless_asked(tmp_path):
    q = ca.SX.sym("q", 2)
    f = ca.Function("f", [q], [ca.sin(q[0]) * ca.cos(q[1]) + ca.sin(q[1]) + ca.sin(q[0] * q[1])], ["q"], ["y"])
    fast = export_c([f], tmp_path / "fast").source.read_text()
    libm = export_c([f], tmp_path / "libm", fast_trig=False).source.read_text()
    body = fast.split("static int casadi_f0")[1]
    # the input angles are reduced together at the top, other angles call the inlined functions
    assert "psdm_sincos_n(psdm_x, psdm_s, psdm_c, 2);" in body
    assert "psdm_s[0]" in body and "psdm_c[1]" in body and "psdm_s[1]" in body
    assert "psdm_sin(a" in body
    assert not re.search(r"(?<![A-Za-z0-9_])(sin|cos)\(", body)
    assert "psdm_sin" not in libm and re.search(r"(?<![A-Za-z0-9_])sin\(", libm)


@pytest.mark.needs_cc
@needs_cc
def test_hoisted_trig_compiles_and_matches(tmp_path):
    from codegen.build import build_library

    q = ca.SX.sym("q", 3)
    expr = ca.vertcat(ca.sin(q[0]) * ca.cos(q[2]), ca.cos(q[0]) + ca.sin(q[1] * q[2]), ca.cos(q[1]))
    f = ca.Function("f", [q], [expr], ["q"], ["y"])
    library = build_library(export_c([f], tmp_path / "out"), build_dir=tmp_path / "build", flags=("-O2",))
    compiled = library.function("psdm_f")
    for x in ([0.3, -2.0, 7.5], [1e6, 0.1, -3.0], [-1e-9, 250.0, np.pi / 2]):
        np.testing.assert_allclose(np.array(compiled(x)).ravel(), np.array(f(x)).ravel(), rtol=0, atol=1e-15)


def test_hoisting_follows_reassigned_variables_and_skips_unknown_code():
    from codegen.export import _hoist_input_trig

    lines = [
        "static int casadi_f0(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {",
        "  casadi_real a0, a1, a2;",
        "  a0=arg[0]? arg[0][3] : 0;",
        "  a1=psdm_sin(a0);",
        "  a0=(a0*a1);",  # a0 no longer holds q[3]
        "  a2=psdm_cos(a0);",
        "  a0=arg[1]? arg[1][0] : 0;",
        "  a0=psdm_cos(a0);",  # argument read before the assignment
        "  if (res[0]!=0) res[0][0]=a2;",
        "  return 0;",
        "}",
    ]
    out = _hoist_input_trig(lines)
    assert "  psdm_sincos_n(psdm_x, psdm_s, psdm_c, 2);" in out
    assert "  psdm_x[0]=arg[0]? arg[0][3] : 0;" in out and "  psdm_x[1]=arg[1]? arg[1][0] : 0;" in out
    assert "  a1=psdm_s[0];" in out and "  a2=psdm_cos(a0);" in out and "  a0=psdm_c[1];" in out
    assert out.index("  casadi_real a0, a1, a2;") < out.index("  psdm_sincos_n(psdm_x, psdm_s, psdm_c, 2);")
    unknown = lines[:-2] + ["  for (i=0; i<3; ++i) w[i]=a0;"] + lines[-2:]
    assert _hoist_input_trig(unknown) == unknown


def test_inlining_refuses_code_without_the_math_include(tmp_path):
    from codegen.export import _inline_trig
    from psdm_casadi.errors import SolverError

    source = tmp_path / "odd.c"
    source.write_text("double f(double x) { return x; }\n")
    with pytest.raises(SolverError, match="odd.c has no '#include <math.h>'; export with fast_trig=False"):
        _inline_trig(source)
    assert source.read_text() == "double f(double x) { return x; }\n"  # left as it was
