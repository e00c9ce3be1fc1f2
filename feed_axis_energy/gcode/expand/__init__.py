"""Moves that one block expands into: canned cycles, cutter compensation, splines."""
