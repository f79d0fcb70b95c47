"""Pictures: fan images (top view), elevation-azimuth maps."""

from acousim.viz.fan import elaz_figure, fan_figure, full_range_fan

__all__ = ["elaz_figure", "fan_figure", "full_range_fan"]
