"""The Sinumerik dialect: Siemens' NC language read by its own front, moves by the interpreter.

:mod:`.reader` runs a Sinumerik program (variables, control flow, subprograms, cycles,
frames, polar coordinates, the Siemens arc forms) and hands each block that moves or sets a
machine function to :mod:`feed_axis_energy.gcode.interp` as RS274NGC words in machine
coordinates; :mod:`.geometry` and :mod:`.frames` hold the path state that needs,
:mod:`.cycles` the drilling cycles and hole patterns, :mod:`.text` the lexer and expressions,
:mod:`.progfile` a file's labels and structures, :mod:`.detect` when a file is taken as
Sinumerik. ``docs/gcode-design.md`` lists what is read and what is refused.
"""
from .detect import siemens_evidence, SNIFF_LINES
from .reader import (decode_siemens, MAX_CALL_DEPTH, read_siemens_blocks,
                     read_siemens_program, SiemensReader)

__all__ = ['decode_siemens', 'MAX_CALL_DEPTH', 'read_siemens_blocks', 'read_siemens_program',
           'siemens_evidence', 'SiemensReader', 'SNIFF_LINES']
