"""The registry and each controller agree on which controllers are built from a model."""

from __future__ import annotations

import pytest

from rkmpc.control.base import Controller
from rkmpc.control.registry import CONTROLLERS, MODEL_KIND


@pytest.mark.parametrize("name", sorted(CONTROLLERS))
def test_a_controller_takes_a_model_exactly_when_the_registry_says_it_needs_one(name: str) -> None:
    try:
        cls = CONTROLLERS[name].load()
    except ImportError:  # an optional extra (acados) that is not installed
        pytest.skip(f"{name}: its extra is not installed")
    builds_itself = cls.from_settings.__func__ is not Controller.from_settings.__func__  # type: ignore[attr-defined]
    if builds_itself:
        return  # it passes its model itself (rkmpc, rkmpc-paper, nmpc-id)
    assert cls.takes_model == (name in MODEL_KIND)
