"""``psdm codegen``: robot file -> C folder, JSON report, refusal to overwrite, --theta checks."""

import json

import numpy as np
import pytest

from psdm_casadi.cli import main
from psdm_casadi.cli.codegen import read_theta
from psdm_casadi.errors import ParameterError
from tests.conftest import DENSO_FILE


def test_codegen_denso_json(tmp_path, capsys, denso, denso_model):
    pytest.importorskip("psdm_casadi.symbolic")
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    theta_file = tmp_path / "theta.csv"
    np.savetxt(theta_file, theta[None, :], delimiter=",")
    out = tmp_path / "out"
    code = main(["codegen", str(DENSO_FILE), "--out", str(out), "--theta", str(theta_file), "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["out"] == str(out) and report["compiled"] is False
    assert "psdm_inverse_dynamics" in report["functions"] and "psdm_inverse_dynamics_theta" in report["functions"]
    assert set(report["n_instructions"]) == set(report["functions"])
    assert report["n_instructions"]["psdm_inverse_dynamics"] < report["n_instructions"]["psdm_inverse_dynamics_theta"]
    assert (out / "psdm_dynamics.c").exists() and (out / "main.c").exists() and (out / "Makefile").exists()
    assert "psdm_regressor" in report["functions"]
    assert report["lane_regressor"] is None  # the Denso's scalar regressor is smaller than the vector one


def test_codegen_refuses_non_empty_out(tmp_path, capsys):
    (tmp_path / "mine.c").write_text("int main(void) { return 0; }")
    code = main(["codegen", str(DENSO_FILE), "--out", str(tmp_path)])
    assert code == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (tmp_path / "mine.c").read_text().startswith("int main")


def test_codegen_theta_length_checked(tmp_path, capsys):
    pytest.importorskip("psdm_casadi.symbolic")
    theta_file = tmp_path / "theta.txt"
    np.savetxt(theta_file, np.ones(3))
    code = main(["codegen", str(DENSO_FILE), "--out", str(tmp_path / "out"), "--theta", str(theta_file)])
    assert code == 2
    assert "--theta must have 32 values" in capsys.readouterr().err


def test_read_theta_formats_and_errors(tmp_path):
    values = np.array([1.0, -2.5, 3.25])
    np.save(tmp_path / "t.npy", values)
    np.savetxt(tmp_path / "t.csv", values[None, :], delimiter=",")
    np.savetxt(tmp_path / "t.txt", values)
    for name in ("t.npy", "t.csv", "t.txt"):
        np.testing.assert_array_equal(read_theta(tmp_path / name), values)
    (tmp_path / "bad.txt").write_text("one two")
    with pytest.raises(ParameterError, match="--theta"):
        read_theta(tmp_path / "bad.txt")
    with pytest.raises(ParameterError, match="--theta"):
        read_theta(tmp_path / "missing.npy")


@pytest.mark.slow
@pytest.mark.needs_cc
def test_codegen_compile_and_load(tmp_path, capsys, denso, denso_model, rng):
    pytest.importorskip("psdm_casadi.symbolic")
    import casadi as ca

    from psdm_casadi.oracle import PinocchioOracle

    out = tmp_path / "out"
    assert main(["codegen", str(DENSO_FILE), "--out", str(out), "--compile", "--json"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["compiled"] is True
    inverse = ca.external("psdm_inverse_dynamics", str(out / "libpsdm_dynamics.so"))
    q, qd, qdd = rng.uniform(-2, 2, (3, denso.n_dof))
    tau = np.array(inverse(q, qd, qdd), dtype=float).ravel()
    np.testing.assert_allclose(tau, PinocchioOracle(denso).rnea(q, qd, qdd), rtol=1e-9, atol=1e-9)


def test_codegen_forms_of_a_saved_model(tmp_path, capsys, denso, denso_model):
    """A model file exports the sum form alone, the recursive form with --robot (a much smaller graph)."""
    model_file = denso_model.save(tmp_path / "denso.npz")
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    np.save(tmp_path / "theta.npy", theta)
    runs = {}
    for form, extra in (("sum", []), ("recursive", ["--robot", str(DENSO_FILE)])):
        out = tmp_path / form
        assert (
            main(
                [
                    "codegen",
                    str(model_file),
                    "--out",
                    str(out),
                    "--theta",
                    str(tmp_path / "theta.npy"),
                    "--json",
                    *extra,
                ]
            )
            == 0
        )
        runs[form] = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert runs[form]["form"] == form
    assert (
        runs["recursive"]["n_instructions"]["psdm_inverse_dynamics"]
        < runs["sum"]["n_instructions"]["psdm_inverse_dynamics"] / 4
    )
    code = main(["codegen", str(model_file), "--out", str(tmp_path / "none"), "--form", "recursive"])
    assert code == 2 and "--robot ROBOT_FILE" in capsys.readouterr().err
    code = main(["codegen", str(DENSO_FILE), "--out", str(tmp_path / "twice"), "--robot", str(DENSO_FILE)])
    assert code == 2 and "Drop --robot" in capsys.readouterr().err


def test_codegen_and_derive_take_overwrite_as_every_other_command_does(tmp_path, capsys):
    """A user who ran 'psdm identify --overwrite' types --overwrite for codegen too (argparse refused it as an
    unrecognized argument once, then the refusal still asked for --force); a file psdm did not write is still
    refused, a model it wrote replaced; --force is its deprecated old name: it works and says so, the help hides it."""
    (tmp_path / "mine.c").write_text("int main(void) { return 0; }")
    assert main(["codegen", str(DENSO_FILE), "--out", str(tmp_path), "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments" not in err and "mine.c" in err and "--force" not in err
    assert main(["codegen", str(DENSO_FILE), "--out", str(tmp_path), "--force"]) == 2
    err = capsys.readouterr().err
    assert "--force is the old name of --overwrite" in err and "mine.c" in err
    with pytest.raises(SystemExit):
        main(["codegen", "--help"])
    usage = capsys.readouterr().out
    assert "--overwrite" in usage and "--force" not in usage
    assert (tmp_path / "mine.c").read_text().startswith("int main")
    out = tmp_path / "denso.npz"
    assert main(["derive", str(DENSO_FILE), "-o", str(out), "--json"]) == 0
    assert main(["derive", str(DENSO_FILE), "-o", str(out), "--json"]) == 2  # refused without the option
    assert main(["derive", str(DENSO_FILE), "-o", str(out), "--overwrite", "--json"]) == 0
    assert main(["derive", str(DENSO_FILE), "-o", str(out), "--force", "--json"]) == 0
    assert "--force is the old name of --overwrite" in capsys.readouterr().err
