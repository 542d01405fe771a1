import json

import numpy as np
import pytest

from psdm_casadi import load_model
from psdm_casadi.errors import ModelFileError, ShapeError


def test_save_load_round_trip_is_exact(denso_model, tmp_path):
    path = denso_model.save(tmp_path / "denso.npz")
    loaded = load_model(path)
    for name in ("exponents", "reduction", "parameter_map", "revolute"):
        assert getattr(loaded, name).tobytes() == getattr(denso_model, name).tobytes()
    assert loaded.base_names == denso_model.base_names
    assert loaded.standard_names == denso_model.standard_names
    assert loaded.gravity_magnitude == denso_model.gravity_magnitude
    assert loaded == denso_model


def test_save_refuses_to_overwrite(denso_model, tmp_path):
    path = denso_model.save(tmp_path / "m.npz")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        denso_model.save(path)
    denso_model.save(path, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npz"]  # no temporary left behind


def test_load_rejects_other_versions_and_files(denso_model, tmp_path):
    path = denso_model.save(tmp_path / "m.npz")
    with np.load(path) as data:
        arrays = dict(data)
    header = json.loads(str(arrays["header"]))
    header["version"] = 99
    arrays["header"] = np.array(json.dumps(header))
    np.savez(tmp_path / "v99.npz", **arrays)
    with pytest.raises(ModelFileError, match="version 99 is not supported"):
        load_model(tmp_path / "v99.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ModelFileError, match="not a psdm-casadi model"):
        load_model(tmp_path / "junk.npz")
    with pytest.raises(ModelFileError, match="does not exist"):
        load_model(tmp_path / "missing.npz")


def test_equations_read_like_table_4(denso_model):
    text = denso_model.equations()
    lines = text.splitlines()
    assert len(lines) == 32
    assert sum("[gravity" in line for line in lines) == 9
    assert lines[-1].split("=")[1].strip() == "Im6"


def test_shape_errors_name_the_argument(denso_model):
    with pytest.raises(ShapeError, match=r"q must have shape \(n_samples, 6\)"):
        denso_model.regressor(np.zeros(5), np.zeros(5), np.zeros(5))
    with pytest.raises(ShapeError, match="theta must have 32"):
        denso_model.inverse_dynamics(np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(3))
    with pytest.raises(ShapeError, match="standard parameters must be"):
        denso_model.base_parameters(np.zeros(7))


def test_model_is_immutable(denso_model):
    with pytest.raises(ValueError):
        denso_model.reduction[0, 0, 0] = 1.0
