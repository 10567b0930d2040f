import dataclasses

import pytest

from xted.config import parse_overrides
from xted.errors import InputError


@dataclasses.dataclass(frozen=True)
class Example:
    flag: bool = False
    width: int = 4
    scale: float | None = 1.0


@pytest.mark.parametrize("text, value", [("true", True), ("1", True), ("Yes", True), ("false", False), ("0", False),
                                         ("no", False)])
def test_boolean_overrides_accept_the_usual_words(text, value):
    assert parse_overrides(Example, [f"flag={text}"]) == {"flag": value}


@pytest.mark.parametrize("pair", ["flag=tru", "flag=", "flag=2", "width=four", "scale=big", "depth=3", "width"])
def test_bad_overrides_name_the_pair(pair):
    with pytest.raises(InputError, match="--set"):
        parse_overrides(Example, [pair])


def test_typed_values_and_none():
    assert parse_overrides(Example, ["width=8", "scale=none"]) == {"width": 8, "scale": None}
