"""The catalogue's check itself: it must fail on a traceback, a wrong code, a vague message or a touched file."""

import pytest

from tests.catalogue.harness import BadInput, check_refusal


def test_a_clean_refusal_passes(tmp_path, capsys, monkeypatch):
    case = BadInput("missing robot", ("derive", "no_such_robot.toml"), expect=("no_such_robot.toml", "check the path"))
    assert "does not exist" in check_refusal(case, tmp_path, capsys, monkeypatch)


@pytest.mark.parametrize(
    "case",
    [
        BadInput("wrong code", ("derive", "no_such_robot.toml"), expect=(), exit_code=1),
        BadInput("vague message", ("derive", "no_such_robot.toml"), expect=("the fix that is not there",)),
    ],
    ids=str,
)
def test_the_check_catches_a_broken_contract(tmp_path, capsys, monkeypatch, case):
    with pytest.raises(AssertionError):
        check_refusal(case, tmp_path, capsys, monkeypatch)
