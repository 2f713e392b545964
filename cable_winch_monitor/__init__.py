"""Monitor for the four winches of a mine-shaft sinking platform: pose, cable tensions, wall clearance."""

__version__ = "0.1.0"
