"""The steel plate's options: checked when built, named when unknown, saved as plain values."""

import json

import pytest
from mppf.sim.plate.options import PlateOptions

from mppf.core.errors import InputError


def test_options_are_checked_and_converted_when_built():
    options = PlateOptions(layers=4.0, springback=0, grid_spacing_mm=75)
    assert options.layers == 4 and isinstance(options.layers, int)
    assert options.springback is False and options.grid_spacing_mm == 75.0
    assert json.loads(json.dumps(options.to_dict()))["layers"] == 4
    with pytest.raises(InputError, match="layers must be from 2 to 64, got 1"):
        PlateOptions(layers=1)
    with pytest.raises(InputError, match="response factor"):
        PlateOptions(response_factor=0.0)


def test_an_unknown_option_is_named():
    with pytest.raises(InputError, match="unknown plate option.*grid_mm") as info:
        PlateOptions.of({"grid_mm": 50.0})
    assert "grid_spacing_mm" in info.value.hint
