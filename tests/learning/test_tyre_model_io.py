"""Identified models with tyres in model files (version 4): round trip, older versions, errors."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import pytest

from rkmpc.core.errors import InputFileError
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.learning.io import load_identified, load_model, save_identified
from rkmpc.learning.tyre_model import AxleCurve, IdentifiedTyres


def _model(tyres: bool = True) -> IdentifiedModel:
    fitted = IdentifiedTyres(
        structure="pacejka",
        front=AxleCurve.pacejka(6.1, 0.4182, 1.9),
        rear=AxleCurve.pacejka(7.0, 0.5624, 1.6),
        status="identified",
        status_reason="pacejka predicts held-out data with a score 0.2, the nominal tyres 1.3",
        fitted_on="slip_angle",
        wheel="measured",
        servo="identified",
        n_samples=1099,
        folds=5,
        heldout_score=0.2,
        nominal_score=1.3,
        yaw_rate_rmse=0.016,
        nominal_yaw_rate_rmse=0.03,
        lateral_velocity_rmse=0.001,
        nominal_lateral_velocity_rmse=0.002,
        slip_reach=(0.16, 0.10),
        candidates=(("nominal", 1.3), ("grip", 0.35), ("linear", 0.6), ("pacejka", 0.2)),
        warnings=("tyres: the data reach 0.160 rad on the front axle, 60 % of the fitted peak",),
    )
    model = IdentifiedModel(0.158, 0.009, math.nan, 0.78, 1099, "nominal", status="identified")
    return replace(model, tyres=fitted if tyres else None)


def test_a_model_with_tyres_round_trips_and_serves_both_identified_controllers(tmp_path):
    path = tmp_path / "model.json"
    model = _model()
    save_identified(model, path)
    payload = json.loads(path.read_text())
    assert payload["version"] == 4
    assert payload["model"]["tyres"]["front"] == {"kind": "pacejka", "parameters": [6.1, 0.4182, 1.9, 0.0]}
    assert load_identified(path) == model
    assert load_model(path, "identified-tyres") == model  # nmpc-id
    assert load_model(path, "identified") == model  # lmpc-id reads it too and ignores the tyres


def test_models_without_tyres_load_but_nmpc_id_refuses_them(tmp_path):
    path = tmp_path / "model.json"
    save_identified(_model(tyres=False), path)
    assert load_identified(path).tyres is None
    with pytest.raises(InputFileError, match=r"without tyres.*nmpc-id needs one") as info:
        load_model(path, "identified-tyres")
    assert info.value.field == "tyres"
    # A version 3 file (no tyres field) loads without tyres; with one it is refused.
    payload = json.loads(path.read_text())
    del payload["model"]["tyres"]
    path.write_text(json.dumps({**payload, "version": 3}))
    assert load_identified(path).tyres is None
    save_identified(_model(), path)
    path.write_text(json.dumps({**json.loads(path.read_text()), "version": 3}))
    with pytest.raises(InputFileError, match=r"expected the fields .* \(version 3\)"):
        load_identified(path)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"front": {"kind": "cubic", "parameters": [1.0]}}, "AxleCurve.kind"),
        ({"rear": {"kind": "linear", "parameters": [-3.0]}}, "AxleCurve.parameters"),
        ({"status": "nominal"}, "nominal goes with nominal"),
        ({"folds": -1}, "folds"),
        ({"extra": 1}, "expected the fields"),
    ],
)
def test_bad_tyres_in_a_file_name_the_problem(tmp_path, change, message):
    path = tmp_path / "model.json"
    save_identified(_model(), path)
    payload = json.loads(path.read_text())
    payload["model"]["tyres"].update(change)
    path.write_text(json.dumps(payload))
    with pytest.raises(InputFileError, match=message) as info:
        load_identified(path)
    assert info.value.field == "model"
