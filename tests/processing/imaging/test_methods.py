"""Method names parsed once (processing.imaging.methods): every name of METHODS against a
table written here from the naming rule of the docs, and the refusals."""

import re

import pytest

import processing as P

#: the naming rule ``base[-smoothing][-cf][-wb|-bb]`` as a regular expression
RULE = re.compile(r"^(das|music|capon|dmas([2-5]))(-(fss|fbss))?(-cf)?(-(wb|bb))?$")


@pytest.mark.parametrize("name", P.METHODS)
def test_every_method_parses_as_its_name_reads(name):
    m = RULE.match(name)
    assert m, name
    spec = P.parse_method(name)
    family = {None: "narrowband", "wb": "wideband", "bb": "broadband"}[m.group(7)]
    assert spec.name == name
    assert spec.family == family
    assert spec.base == ("dmas" if m.group(2) else m.group(1))
    assert spec.order == (int(m.group(2)) if m.group(2) else 1)
    assert spec.coherence_factor == bool(m.group(5))
    assert spec.smoothing == (m.group(4) or "")
    assert spec.requires_ura == P.requires_ura(name) == bool(m.group(4))


def test_the_families_partition_the_methods():
    fam = {n: P.parse_method(n).family for n in P.METHODS}
    assert {n for n, f in fam.items() if f == "broadband"} == set(P.BROADBAND_METHODS)
    assert {n for n, f in fam.items() if f == "wideband"} == set(P.WIDEBAND_METHODS)
    assert {n for n, f in fam.items() if f == "narrowband"} == set(P.NARROWBAND_METHODS)
    assert P.parse_method("dmas3-cf-bb").order == 3


@pytest.mark.parametrize("bad", ["DAS", "das-wb", "dmas6-bb", "music_fbss", "", "capon-cf"])
def test_unknown_names_are_refused_naming_the_value(bad):
    with pytest.raises(P.InputError, match="method"):
        P.parse_method(bad)
