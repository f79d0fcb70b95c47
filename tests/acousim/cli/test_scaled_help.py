"""An option given in another unit than its declaration's (kHz for a setting in Hz)
shows its range, default and unit in the option's unit in --help."""

from __future__ import annotations

import pytest

from acousim.cli import main
from acousim.experiments import StudyConfig
from processing.base.settings import settings_of


def test_reproduce_help_gives_the_steering_frequency_in_khz(capsys):
    decl = settings_of(StudyConfig)["frequency_hz"]
    with pytest.raises(SystemExit):
        main(["reproduce", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    lo, hi, default = decl.lo / 1e3, decl.hi / 1e3, decl.default / 1e3
    assert f"kHz, [{lo:g}, {hi:g}], default {default!r}" in text  # 31.25, not 31250.0
    assert "Hz, [1," not in text
