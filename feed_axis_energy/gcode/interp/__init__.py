"""The modal interpreter: blocks -> canonical moves with full modal state.

Motion words, feeds, non-motion codes, coordinate systems, offsets and the tool table;
cycles, cutter compensation and splines come from :mod:`feed_axis_energy.gcode.expand`.
"""
