"""The derivation against Pinocchio, the counts published with the method, and the published Denso model."""

import numpy as np
import pytest

from psdm_casadi import DeriveOptions, derive_psdm, from_urdf
from psdm_casadi.derive import check_against_oracle
from psdm_casadi.errors import ParameterError
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR
from psdm_casadi.samples import kr6, scara, two_link
from psdm_casadi.sampling import random_standard_parameters
from tests.conftest import REFERENCE_PSDM, example_robot_urdf


@pytest.mark.parametrize(
    "robot, p, l",
    [
        (two_link(reduced=True), 10, 4),
        (two_link(), 18, 6),
        (scara(), 69, 8),
        (kr6(), 6086, 36),
    ],
    ids=["two-link-reduced", "two-link", "scara", "kr6"],
)
def test_published_counts(robot, p, l):
    model = derive_psdm(robot)
    assert (model.n_functions, model.n_base) == (p, l)
    assert model.metadata["max_rel_error_vs_pinocchio"] < 1e-9


def test_denso_counts(denso_model):
    assert (denso_model.n_functions, denso_model.n_base, denso_model.n_gravity) == (1318, 32, 9)
    # the composition published with the model: 47 gravity, 313 qdd, 348 qd^2, 610 qd_i qd_j functions
    n = 6
    acc = denso_model.exponents[4 * n :].sum(axis=0)
    vel = denso_model.exponents[3 * n : 4 * n]
    assert int(denso_model.gravity_functions.sum()) == 47
    assert int((acc == 1).sum()) == 313
    assert int((vel == 2).any(axis=0).sum()) == 348
    assert int(((vel == 1).sum(axis=0) == 2).sum()) == 610


def _reference():
    if not (REFERENCE_PSDM / "supplementary_data_E_csv.csv").exists():
        pytest.skip("../shared/reference/psdm is absent")
    exponents = np.loadtxt(REFERENCE_PSDM / "supplementary_data_E_csv.csv", delimiter=",").astype(int)
    p_flat = np.loadtxt(REFERENCE_PSDM / "supplementary_data_P_csv.csv", delimiter=",")
    reduction = p_flat.reshape(exponents.shape[1], 32, 6, order="F")
    theta = np.loadtxt(REFERENCE_PSDM / "supplementary_data_theta_b_csv.csv")
    return exponents, reduction, theta


def test_denso_function_set_equals_the_published_one(denso_model):
    exponents, _, _ = _reference()
    ours = {tuple(c) for c in denso_model.exponents.T.astype(int)}
    theirs = {tuple(c) for c in exponents.T}
    assert ours == theirs
    # gravity and acceleration functions come in the published order too
    assert np.array_equal(denso_model.exponents[:, :360].astype(int), exponents[:, :360])


def test_denso_model_spans_the_published_model(denso_model, denso, rng):
    """Our base parameters are an invertible linear map of the published ones: same torques for every theta."""
    published, theta_published = _published_model(denso_model.standard_names)
    from psdm_casadi.sampling import random_states

    q, qd, qdd = random_states(denso, 300, rng)
    y_ours = denso_model.regressor(q, qd, qdd).reshape(-1, 32)
    y_published = published.regressor(q, qd, qdd).reshape(-1, 32)
    transform, *_ = np.linalg.lstsq(y_ours, y_published, rcond=None)
    assert np.abs(y_ours @ transform - y_published).max() < 1e-9 * np.abs(y_published).max()
    assert np.linalg.matrix_rank(transform) == 32
    # so the published identified parameters carry over exactly
    tau_published = y_published @ theta_published
    theta_ours = transform @ theta_published
    assert np.allclose(y_ours @ theta_ours, tau_published, rtol=0, atol=1e-9 * np.abs(tau_published).max())


def _published_model(standard_names):
    exponents, reduction, theta = _reference()
    from psdm_casadi.model import PSDMModel

    model = PSDMModel(
        exponents=exponents,
        reduction=reduction,
        parameter_map=np.zeros((32, 66)),
        base_names=[f"t{i}" for i in range(32)],
        standard_names=standard_names,
        gravity_magnitude=9.806132,
        revolute=np.ones(6, bool),
    )
    return model, theta


def test_denso_published_parameters_give_an_indefinite_mass_matrix(denso_model, rng):
    """The reference README's caution: D(5,5) is the constant -0.0062 with the published theta."""
    published, theta = _published_model(denso_model.standard_names)
    zeros = np.zeros(6)
    for q in rng.uniform(-2, 2, size=(5, 6)):
        column = published.regressor(q, zeros, np.eye(6)[4]) - published.regressor(q, zeros, zeros)
        assert column[4] @ theta == pytest.approx(-0.00622, abs=5e-5)


URDFS = [
    ("ur_description/urdf/ur5_robot.urdf", ()),
    ("panda_description/urdf/panda.urdf", ("panda_finger_joint1", "panda_finger_joint2")),
    ("z1_description/urdf/z1.urdf", ("jointGripper",)),
]


@pytest.fixture(scope="module", params=URDFS, ids=["ur5", "panda", "z1"])
def urdf_robot_and_model(request):
    relative, locked = request.param
    robot = from_urdf(example_robot_urdf(relative), locked_joints=locked)
    return robot, derive_psdm(robot)


def test_urdf_robots_match_rnea_on_1000_states(urdf_robot_and_model, rng):
    robot, model = urdf_robot_and_model
    assert check_against_oracle(model, robot, rng, n_samples=1000) < 1e-9
    # and with the URDF's own inertial parameters
    assert check_against_oracle(model, robot, rng, n_samples=200, parameters=robot.nominal_dynamic_parameters()) < 1e-9


@pytest.mark.parametrize("make", [scara, kr6], ids=["scara", "kr6"])
def test_dh_robots_match_rnea_on_1000_states(make, rng):
    robot = make()
    model = derive_psdm(robot)
    assert check_against_oracle(model, robot, rng, n_samples=1000) < 1e-9


def test_denso_matches_rnea_on_1000_states(denso, denso_model, rng):
    assert check_against_oracle(denso_model, denso, rng, n_samples=1000) < 1e-9
    assert (
        check_against_oracle(denso_model, denso, rng, n_samples=200, parameters=denso.nominal_dynamic_parameters())
        < 1e-9
    )


def test_derivation_is_deterministic_byte_for_byte(denso, denso_model):
    again = derive_psdm(denso, DeriveOptions(seed=7))
    assert again.exponents.tobytes() == denso_model.exponents.tobytes()
    assert again.reduction.tobytes() == denso_model.reduction.tobytes()
    assert again.parameter_map.tobytes() == denso_model.parameter_map.tobytes()


def test_reduction_is_sparse_and_normalised(denso_model):
    """Each column of P starts (function-major within joint-major order) with a 1."""
    p = denso_model.reduction
    flat = p.transpose(2, 0, 1).reshape(-1, p.shape[1])  # joint-major, function-minor rows
    for column in flat.T:
        first = column[np.nonzero(column)[0][0]]
        assert first == 1.0
    assert np.count_nonzero(p) < 0.05 * p.size


def test_gravity_parameters_are_those_of_the_gravity_regressor(denso_model, rng):
    q = rng.uniform(-2, 2, size=(50, 6))
    y = denso_model.gravity_regressor(q)
    used = np.abs(y).max(axis=(0, 1)) > 0
    assert np.array_equal(used, denso_model.gravity_mask)


def test_drive_inertia_is_a_base_parameter_of_the_last_joint(denso_model):
    """theta for joint 6 acceleration on joint 6 is Im6 alone (link 6 massless), as in the paper's Table 4."""
    row = denso_model.parameter_map[-1]
    names = [n for n, c in zip(denso_model.standard_names, row) if c != 0]
    assert names == ["Im6"]


def test_options_are_validated():
    with pytest.raises(ParameterError, match="DeriveOptions.n_check"):
        DeriveOptions(n_check=0)
    with pytest.raises(ParameterError, match="DeriveOptions.tolerance"):
        DeriveOptions(tolerance=2.0)
    with pytest.raises(ParameterError, match="either options or seed"):
        derive_psdm(two_link(), DeriveOptions(), seed=1)


def test_random_parameters_respect_the_assumptions(denso, rng):
    params = random_standard_parameters(denso, rng)
    assert np.all(params[5, :10] == 0)  # link 6 massless
    assert params[4, 1] == 0  # m rx5 = 0 because rx5 = 0


def test_shipped_scara_file_is_prismatic_and_derives():
    from psdm_casadi import load_robot

    robot = load_robot(BUILTIN_ROBOTS_DIR / "scara.toml")
    assert [j.kind for j in robot.joints] == ["revolute", "revolute", "prismatic", "revolute"]
    model = derive_psdm(robot)
    assert (model.n_functions, model.n_base) == (69, 8)
    rng = np.random.default_rng(3)
    assert check_against_oracle(model, robot, rng, n_samples=1000, parameters=robot.nominal_dynamic_parameters()) < 1e-9
