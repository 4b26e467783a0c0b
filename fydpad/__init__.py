"""The FYD-pad device and master station: softness, texture, motors, station, CLI."""

__version__ = "0.1.0"
