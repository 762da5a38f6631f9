"""The contract between data, model and car: what a data set or model was made with, and the check."""

from __future__ import annotations

import json
import warnings
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.core.errors import ContractError, ContractWarning, InputFileError, ParameterError
from rkmpc.learning.contract import CONTRACT_KEY, Provenance, contract_of
from rkmpc.learning.data.dataset import TransitionDataset

MADE = Provenance(
    vehicle="f1tenth",
    plant="f1tenth",
    dt=0.05,
    wheelbase=0.307,
    scale=0.1,
    features=("speed",),
    state_min=(0.5,),
    state_max=(3.5,),
)
#: Another value of each checked field, and how the message shows both.
OTHER = {
    "vehicle": ("fullsize", "vehicle = 'f1tenth'", "vehicle = 'fullsize'"),
    "plant": ("gym", "plant = 'f1tenth'", "plant = 'gym'"),
    "dt": (0.01, "dt = 0.05 s", "dt = 0.01 s"),
    "wheelbase": (2.579, "wheelbase = 0.307 m", "wheelbase = 2.579 m"),
    "scale": (1.0, "scale = 0.1", "scale = 1"),
}


@pytest.mark.parametrize("field", sorted(OTHER))
def test_each_field_that_differs_is_refused_naming_file_field_and_both_values(field):
    value, was, uses = OTHER[field]
    run = replace(MADE, **{field: value})
    with pytest.raises(ContractError) as info:
        MADE.check(run, source="model.npz", made="trained")
    message = str(info.value)
    assert f"model.npz was trained with {was}; this run uses {uses}" in message
    assert (
        message.endswith("(pass allow_mismatch=True to use it anyway)") and "--allow-mismatch" not in message
    )
    assert info.value.for_command_line().endswith("(give --allow-mismatch to use it anyway)")
    assert info.value.source == "model.npz"


def test_the_example_message_reads_as_a_sentence():
    with pytest.raises(
        ContractError, match=r"^model\.npz was trained with dt = 0\.01 s; this run uses dt = 0\.05 s"
    ):
        replace(MADE, dt=0.01).check(MADE, source="model.npz", made="trained")


def test_every_mismatch_is_named_at_once():
    run = Provenance(vehicle="fullsize", plant="gym", dt=0.01, wheelbase=2.579, scale=1.0)
    with pytest.raises(ContractError) as info:
        MADE.check(run, source="data.npz", made="recorded")
    assert all(f"{name} = " in str(info.value) for name in OTHER)


@pytest.mark.parametrize("field", sorted(OTHER))
def test_an_allowed_mismatch_warns_and_returns_the_warning_to_record(field):
    run = replace(MADE, **{field: OTHER[field][0]})
    with pytest.warns(ContractWarning, match=field) as caught:
        issued = MADE.check(run, source="model.npz", allow_mismatch=True)
    assert len(issued) == 1 and "(allowed)" in issued[0] and field in issued[0]
    assert [str(w.message) for w in caught] == list(issued)


def test_matching_and_unknown_fields_pass_silently():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert MADE.check(replace(MADE, dt=0.05 * (1 + 1e-9)), source="m") == ()
        # Neither side knowing a field skips it: a controller does not know the track scale,
        # random-excitation data have none.
        assert MADE.check(Provenance(vehicle="f1tenth", dt=0.05), source="m") == ()
        assert replace(MADE, scale=None).check(replace(MADE, scale=1.0), source="m") == ()


def test_a_file_made_before_contracts_loads_and_warns_once():
    old = contract_of({}, dt=0.05)
    assert not old.recorded and old.vehicle is None and old.dt == 0.05
    with pytest.warns(ContractWarning) as caught:
        issued = old.check(MADE, source="old.npz")
    assert len(caught) == 1 and len(issued) == 1
    assert "old.npz was made before contracts" in issued[0]
    assert "vehicle, plant, wheelbase, scale" in issued[0]
    # What it does know is still checked.
    with pytest.raises(ContractError, match=r"dt = 0\.05 s; this run uses dt = 0\.01 s"):
        old.check(replace(MADE, dt=0.01), source="old.npz")


def test_json_round_trip_and_bad_contracts():
    assert Provenance.from_json(json.loads(json.dumps(MADE.to_json()))) == MADE
    with pytest.raises(ParameterError, match="unknown contract fields"):
        Provenance.from_json({**MADE.to_json(), "speed": 3.0})
    with pytest.raises(ParameterError, match="dt"):
        Provenance(dt=0.0)
    with pytest.raises(ParameterError, match="vehicle"):
        Provenance(vehicle="")
    with pytest.raises(ParameterError, match=r"Provenance\.plant must be None or a non-empty string"):
        Provenance(plant=0.05)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="features"):
        Provenance(features=("speed",), state_min=(), state_max=())
    with pytest.raises(ParameterError, match="exceeds"):
        Provenance(features=("speed",), state_min=(2.0,), state_max=(1.0,))


def test_ranges_skip_unmeasured_columns_and_merge():
    values = np.array([[1.0, np.nan, -0.2], [3.0, np.nan, 0.4]])
    made = Provenance(dt=0.05).with_ranges(("speed", "yaw_rate", "steer_angle"), values)
    assert made.features == ("speed", "steer_angle")
    assert made.state_min == (1.0, -0.2) and made.state_max == (3.0, 0.4)
    other = replace(made, scale=0.1, state_min=(0.5, 0.0), state_max=(2.0, 0.5))
    merged = made.merged(other)
    assert merged.scale is None  # the two disagree: unknown
    assert merged.dt == 0.05
    assert merged.state_min == (0.5, -0.2) and merged.state_max == (3.0, 0.5)


# ---------------------------------------------------------------------------- data sets


def _data(dt: float = 0.05, metadata: dict | None = None) -> TransitionDataset:
    rng = np.random.default_rng(0)
    n = 20
    obs = np.zeros((n, 7))
    obs[:, 3] = rng.uniform(1.0, 2.0, n)
    obs[:, 4:] = np.nan
    return TransitionDataset(
        obs=obs,
        command=np.zeros((n, 2)),
        next_obs=obs.copy(),
        dt=dt,
        episode=np.zeros(n, dtype=int),
        metadata=metadata or {},
    )


def test_a_data_set_carries_its_contract_through_its_file(tmp_path):
    data = _data().with_contract(Provenance(vehicle="f1tenth", wheelbase=0.307, scale=0.1))
    contract = data.contract
    assert contract.recorded and contract.dt == 0.05 and contract.vehicle == "f1tenth"
    assert contract.features == ("x", "y", "yaw", "speed")  # the unmeasured columns are left out
    assert contract.state_min[3] == pytest.approx(data.obs[:, 3].min())
    data.save(tmp_path / "d.npz")
    assert TransitionDataset.load(tmp_path / "d.npz").contract == contract


def test_an_old_data_set_knows_only_its_dt():
    contract = _data(dt=0.01).contract
    assert not contract.recorded and contract.dt == 0.01 and contract.vehicle is None


def test_a_contract_that_disagrees_with_the_data_is_refused(tmp_path):
    bad = {CONTRACT_KEY: replace(MADE, dt=0.01).to_json()}
    with pytest.raises(ParameterError, match="contract"):
        _data(metadata=bad)
    good = _data().with_contract(MADE)
    good.save(tmp_path / "d.npz")
    payload = dict(np.load(tmp_path / "d.npz"))
    payload["metadata"] = np.str_(json.dumps({CONTRACT_KEY: {"dt": "fast"}}))
    np.savez(tmp_path / "bad.npz", **payload)
    with pytest.raises(InputFileError, match=r"bad\.npz \[metadata\.contract\]"):
        TransitionDataset.load(tmp_path / "bad.npz")


def test_concatenated_data_merge_their_contracts():
    a = _data().with_contract(Provenance(vehicle="f1tenth", wheelbase=0.307, scale=0.1))
    b = _data().with_contract(Provenance(vehicle="f1tenth", wheelbase=0.307, scale=1.0))
    joined = TransitionDataset.concatenate([a, b]).contract
    assert joined.recorded and joined.vehicle == "f1tenth" and joined.scale is None
    assert not TransitionDataset.concatenate([a, _data()]).contract.recorded
