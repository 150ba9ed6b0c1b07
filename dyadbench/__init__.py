"""dyadbench: benchmark and metrics toolkit for dyadic 3D head motion generation."""

__version__ = "0.1.0"
