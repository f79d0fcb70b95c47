"""processing.base.settings: each kind accepts exactly what its declaration allows."""

import dataclasses
import math

import numpy as np
import pytest

from processing.base.errors import InputError
from processing.base.settings import Setting, check, read_table, setting, settings_of, validate

CASES = [
    # (declaration, accepted -> normalised, refused)
    (
        Setting("float", lo=0, hi=1),
        [(0, 0.0), (1, 1.0), (np.float32(0.5), 0.5)],
        [-1e-9, 1.0000001, math.nan, True, "0.5", None, [0.5]],
    ),
    (
        Setting("float", lo=-60, hi=math.inf),
        [(math.inf, math.inf), (-60, -60.0)],
        [-math.inf, math.nan],
    ),
    (
        Setting("int", lo=0, hi=2**63 - 1),
        [(3, 3), (3.0, 3), (2**63 - 1, 2**63 - 1), (np.int64(5), 5)],
        [2**63, -1, 1.5, math.inf, False, 10**400],
    ),
    (Setting("bool"), [(True, True), (np.bool_(False), False)], [0, 1, "no", "true", None]),
    (Setting("str", choices=("a", "b")), [("a", "a")], ["c", 1, None, ["a"]]),
    (
        Setting("strings", choices=("das", "music")),
        [(["das"], ("das",)), ((), ())],
        ["das", ["das", "bogus"], [1]],
    ),
    (
        Setting("vector", length=3),
        [([1, 2, 3], (1.0, 2.0, 3.0))],
        [[1, 2], [1, 2, math.nan], [1, 2, math.inf], "abc", 5, {"a": 1}],
    ),
    (
        Setting("interval", lo=-90, hi=90),
        [([-10, 10], (-10.0, 10.0)), ((5, 5), (5.0, 5.0))],
        [[10, -10], [-91, 0], [1.0], ["a", 1], 5],
    ),
]


@pytest.mark.parametrize("decl,accepted,refused", CASES)
def test_each_kind(decl, accepted, refused):
    for value, expected in accepted:
        got = check(decl, value, "k")
        assert got == expected and type(got) is type(expected), (value, got)
    for value in refused:
        with pytest.raises(InputError) as exc:
            check(decl, value, "sec.k", "f.toml")
        assert str(exc.value).startswith("f.toml: sec.k = "), str(exc.value)


def test_a_declared_dataclass_checks_construction_and_tables():
    @dataclasses.dataclass(frozen=True)
    class Air:
        wind_m_s: float = setting(0.0, "m/s", 0, 30, "wind speed")
        gusts: bool = setting(False)

        def __post_init__(self):
            validate(self)

    assert Air(wind_m_s=3).wind_m_s == 3.0
    with pytest.raises(InputError, match="Air.wind_m_s = -1"):
        Air(wind_m_s=-1)
    assert read_table(Air, {"wind_m_s": 2}, where="air", file="s.toml") == {"wind_m_s": 2.0}
    with pytest.raises(
        InputError, match=r"s.toml: air.wnd_m_s: unknown key .*did you mean 'wind_m_s'"
    ):
        read_table(Air, {"wnd_m_s": 2}, where="air", file="s.toml")
    with pytest.raises(InputError, match=r"s.toml: air = 5: must be a table"):
        read_table(Air, 5, where="air", file="s.toml")
    assert settings_of(Air)["wind_m_s"].describe() == "float, m/s, [0, 30], default 0.0"
