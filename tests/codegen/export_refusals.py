"""The refusals every file export of a calibrated model makes (``codegen.model_export``), checked alike for URDF and
MJCF: a model without standard parameters is refused, an inconsistent one is written only when asked."""

from __future__ import annotations

import json

import pytest

from identification.calibration.calibrated_model import CalibratedModel
from psdm_casadi.cli import main
from psdm_casadi.errors import ModelFileError


def inconsistent_document(document: dict) -> dict:
    """A copy of a calibrated-model document marked not physically consistent (smallest eigenvalue -0.25)."""
    document = json.loads(json.dumps(document))
    document["standard"].update(consistent=False, min_pseudo_inertia_eigenvalue=-0.25)
    return document


def assert_refuses_bad_models(calibrated, render, export, bad) -> None:
    """``render`` refuses a model without standard parameters; ``export`` refuses an inconsistent model (writing
    nothing to ``bad``) unless ``allow_inconsistent``, and then says so in the file."""
    document = json.loads(json.dumps(calibrated.document))
    document["standard"]["values"] = [None] * len(document["standard"]["values"])
    with pytest.raises(ModelFileError, match="CalibratedModel.standard must hold finite"):
        render(CalibratedModel(document))
    document = inconsistent_document(calibrated.document)
    with pytest.raises(ModelFileError, match="eigenvalue -0.25"):
        export(CalibratedModel(document), bad)
    assert not bad.exists()
    export(CalibratedModel(document), bad, allow_inconsistent=True)
    assert "NOT physically consistent" in bad.read_text()


def assert_cli_refuses_inconsistent(command: str, model, bad, capsys) -> None:
    """``psdm COMMAND MODEL BAD`` exits 1 naming the eigenvalue and writes nothing once MODEL is marked
    inconsistent (MODEL is rewritten so)."""
    model.write_text(json.dumps(inconsistent_document(json.loads(model.read_text()))))
    assert main([command, str(model), str(bad)]) == 1
    assert "eigenvalue -0.25" in capsys.readouterr().err and not bad.exists()
