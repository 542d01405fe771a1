"""Bad option values: refused before any work (no derivation, optimisation or simulation), exit 2, one line
naming the option and the fix, numbers printed plainly, no file written."""

import pytest

from tests.catalogue.harness import BadInput, check_refusal

DENSO, SCARA = "denso_vs6556g", "scara"
EXCITE = ("excite", SCARA, "--out", "traj.csv")
MOTOR = ("experiment", "motor", DENSO, "--out", "motor.csv")
SIMULATE = ("simulate", DENSO, "--out", "data")
SINE = (*SIMULATE, "--experiment", "sine")
MOTOR_RUN = (*SIMULATE, "--experiment", "motor")

CASES = [
    # psdm excite: the CSV options used to fail only after the optimisation
    BadInput("excite --rate 0", (*EXCITE, "--rate", "0"), ("--rate", "got 0", "--rate 100")),
    BadInput("excite --rate -5", (*EXCITE, "--rate", "-5"), ("--rate", "got -5", "--rate 100")),
    BadInput("excite --rate nan", (*EXCITE, "--rate", "nan"), ("--rate", "got nan", "--rate 100")),
    BadInput("excite --rate 1e9", (*EXCITE, "--rate", "1e9"), ("--rate", "samples", "lower --rate")),
    BadInput("excite --periods 0", (*EXCITE, "--periods", "0"), ("--periods", "got 0", "--periods 1")),
    BadInput(
        "excite --periods 2 of sums of sines",
        (*EXCITE, "--periods", "2", "--family", "sum_of_sines"),
        ("--periods", "--family fourier"),
    ),
    BadInput("excite --duration 0", (*EXCITE, "--duration", "0"), ("--duration", "got 0", "--duration 10")),
    BadInput("excite --duration -1", (*EXCITE, "--duration", "-1"), ("--duration", "got -1", "--duration 10")),
    BadInput("excite --duration inf", (*EXCITE, "--duration", "inf"), ("--duration", "got inf", "--duration 10")),
    BadInput("excite --harmonics 0", (*EXCITE, "--harmonics", "0"), ("--harmonics", "got 0", "--harmonics 5")),
    BadInput("excite --terms 0", (*EXCITE, "--terms", "0"), ("--terms", "got 0", "--terms 3")),
    BadInput("excite --starts 0", (*EXCITE, "--starts", "0"), ("--starts", "got 0", "--starts 3")),
    BadInput("excite --samples 0", (*EXCITE, "--samples", "0"), ("--samples", "got 0", "--samples 100")),
    BadInput("excite --max-iter 0", (*EXCITE, "--max-iter", "0"), ("--max-iter", "got 0", "--max-iter 300")),
    BadInput("excite --limit-scale 1.5", (*EXCITE, "--limit-scale", "1.5"), ("--limit-scale", "1.5", "0.9")),
    BadInput("excite --time-limit -3", (*EXCITE, "--time-limit", "-3"), ("--time-limit", "got -3", "leave it out")),
    BadInput("excite --seed -1", (*EXCITE, "--seed", "-1"), ("--seed", "got -1", "--seed 0")),
    BadInput("excite --rate abc", (*EXCITE, "--rate", "abc"), ("--rate", "invalid float value")),
    BadInput("excite --lock on a TOML robot", (*EXCITE, "--lock", "J1"), ("--lock", "remove --lock")),
    # psdm experiment
    BadInput("experiment --joint 7", (*MOTOR, "--joint", "7"), ("--joint", "1..6", "--joint 6")),
    BadInput("experiment without --joint", ("experiment", "friction", DENSO, "--out", "f.csv"), ("--joint 2",)),
    BadInput("experiment --speed 0", (*MOTOR, "--joint", "2", "--speed", "0"), ("--speed", "got 0", "0.25")),
    BadInput("experiment --rate 0", (*MOTOR, "--joint", "2", "--rate", "0"), ("--rate", "got 0", "--rate 100")),
    BadInput(
        "experiment gravity --duration -1",
        ("experiment", "gravity", DENSO, "--duration", "-1"),
        ("--duration", "got -1", "--duration 120"),
    ),
    BadInput("experiment --seed -1", ("experiment", "gravity", DENSO, "--seed", "-1"), ("--seed", "--seed 0")),
    # psdm simulate
    BadInput("simulate --duration -1", (*SINE, "--duration", "-1"), ("--duration", "got -1", "--duration 10")),
    BadInput(
        "simulate --duration 1e9 (3.6 TiB)",
        (*SINE, "--duration", "1e9"),
        ("--duration", "2000000 samples", "1e+12 samples", "shorten --duration"),
    ),
    BadInput(
        "simulate --rate 1e7 over a 120 s gravity jog",
        (*SIMULATE, "--experiment", "gravity", "--rate", "1e7"),
        ("--rate", "2000000 samples", "lower --rate"),
    ),
    BadInput("simulate --rate 0", (*SINE, "--rate", "0"), ("--rate", "got 0", "--rate 1000")),
    BadInput("simulate --substeps 0", (*SINE, "--substeps", "0"), ("--substeps", "got 0", "--substeps 2")),
    BadInput("simulate --joints abc", (*MOTOR_RUN, "--joints", "abc"), ("--joints", "'abc'", "--joints 1,3")),
    BadInput("simulate --joints 0", (*MOTOR_RUN, "--joints", "0"), ("--joints", "got 0", "--joints 1,6")),
    BadInput("simulate --joints 7 of 6", (*MOTOR_RUN, "--joints", "7"), ("--joints", "6 joints", "got 7")),
    BadInput("simulate --payload -2", (*MOTOR_RUN, "--joints", "6", "--payload", "-2"), ("--payload", "got -2", "kg")),
    BadInput("simulate --payload 0", (*MOTOR_RUN, "--payload", "0"), ("--payload", "got 0", "--payload 2")),
    BadInput("simulate --seed -1", (*SINE, "--seed", "-1"), ("--seed", "got -1", "--seed 0")),
    BadInput(
        "simulate a missing --reference",
        (*SIMULATE, "--reference", "nowhere.csv"),
        ("nowhere.csv", "does not exist", "check the path"),
    ),
    # psdm derive, demo, codegen, identify, diagnose
    BadInput("derive --seed -1", ("derive", SCARA, "--seed", "-1"), ("--seed", "got -1", "--seed 0")),
    BadInput("demo --seed -1", ("demo", "--quick", "--out", "r", "--seed", "-1"), ("--seed", "got -1", "--seed 0")),
    BadInput(
        "codegen --library 1lib",
        ("codegen", SCARA, "--out", "c", "--library", "1lib"),
        ("--library", "'1lib'", "--library robot_dynamics"),
    ),
    BadInput(
        "codegen --theta missing",
        ("codegen", SCARA, "--out", "c", "--theta", "theta.npy"),
        ("--theta", "theta.npy", "check the path"),
    ),
    BadInput(
        "identify --data missing",
        ("identify", SCARA, "--data", "nodata", "--out", "model"),
        ("--data", "'nodata'", "check the path"),
    ),
    BadInput(
        "identify --model missing",
        ("identify", SCARA, "--data", "data", "--out", "model", "--model", "m.npz"),
        ("--model", "m.npz", "leave --model out"),
        files={"data/payload.json": "{}"},
    ),
    BadInput(
        "diagnose --max-samples 10",
        ("diagnose", DENSO, "--train", "a.csv", "--validate", "b.csv", "--max-samples", "10"),
        ("--max-samples", "got 10", "--max-samples 250000"),
    ),
    BadInput(
        "diagnose --max-effects -1",
        ("diagnose", DENSO, "--train", "a.csv", "--validate", "b.csv", "--max-effects", "-1"),
        ("--max-effects", "got -1", "--max-effects 4"),
    ),
    BadInput(
        "diagnose --cutoff 0",
        ("diagnose", DENSO, "--train", "a.csv", "--validate", "b.csv", "--cutoff", "0"),
        ("--cutoff", "got 0", "--cutoff 10"),
    ),
    BadInput(
        "diagnose --train missing",
        ("diagnose", DENSO, "--train", "a.csv", "--validate", "b.csv"),
        ("a.csv", "does not exist", "check the path"),
    ),
]


@pytest.mark.parametrize("case", CASES, ids=str)
def test_bad_option_is_refused_before_any_work(case, tmp_path, capsys, monkeypatch):
    err = check_refusal(case, tmp_path, capsys, monkeypatch)
    assert "np.float" not in err and "np.int" not in err
    assert len(err.strip().splitlines()) == 1 or "usage:" in err  # argparse prints its usage first
