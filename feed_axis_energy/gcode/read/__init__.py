"""Reading NC text: lexer, values and expressions, parameters, O-word flow, subprograms.

Lines -> executed :class:`~.block.Block` s (:mod:`.flow`); the modal half is
:mod:`feed_axis_energy.gcode.interp`.
"""
