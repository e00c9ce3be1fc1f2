"""Virtual ball-screw feed axis: actual power and energy from an NC program."""

__version__ = '0.1.0'
