"""The one registry pattern: names to entries, one error naming the unknown name and the known ones."""

from __future__ import annotations

import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.core.registry import Registry, UnknownNameError


def test_entries_keep_their_order_and_unknown_names_are_named_with_the_known_ones():
    fruit = Registry("fruit", {"apple": 1, "pear": 2})
    assert fruit["pear"] == 2 and list(fruit) == ["apple", "pear"] and len(fruit) == 2
    assert "apple" in fruit and "plum" not in fruit and 3 not in fruit
    assert fruit.register("plum", 3) == 3 and list(fruit) == ["apple", "pear", "plum"]
    assert fruit.check("plum") == "plum"
    with pytest.raises(UnknownNameError) as info:
        fruit["aple"]
    error = info.value
    assert str(error) == "unknown fruit 'aple'; did you mean 'apple'? known: apple, pear, plum"
    assert (error.kind, error.name, error.known) == ("fruit", "aple", ["apple", "pear", "plum"])
    assert isinstance(error, ParameterError) and isinstance(error, KeyError) and isinstance(error, ValueError)
    with pytest.raises(UnknownNameError, match=r"^unknown fruit 'kiwi'; known: apple, pear, plum$"):
        fruit.check("kiwi")
    with pytest.raises(UnknownNameError, match="unknown fruit"):
        fruit[["apple"]]  # type: ignore[index]  # not a name at all
    assert fruit.get("kiwi") is None  # a Mapping: get() does not raise


@pytest.mark.parametrize(
    ("name", "match"), [("", "non-empty string"), (3, "non-empty string"), ("apple", "already")]
)
def test_a_bad_or_repeated_name_is_refused(name, match):
    fruit = Registry("fruit", {"apple": 1})
    with pytest.raises(ParameterError, match=match):
        fruit.register(name, 2)  # type: ignore[arg-type]
    assert list(fruit) == ["apple"]


def test_the_packages_registries_share_the_error():
    from rkmpc.config.loader import PRESETS
    from rkmpc.control.registry import CONTROLLERS
    from rkmpc.sim.faults import FAULTS
    from rkmpc.vehicle.registry import PLANTS

    for registry, kind in (
        (CONTROLLERS, "controller"),
        (PLANTS, "plant"),
        (FAULTS, "fault"),
        (PRESETS, "car preset"),
    ):
        with pytest.raises(UnknownNameError, match=rf"^unknown {kind} 'nope'"):
            registry["nope"]
    assert CONTROLLERS["lmpc"].load().__name__ == "LinearMPC"
