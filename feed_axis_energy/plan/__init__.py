"""The planner: canonical moves -> sampled axis motion.

Segments and their path limits (:mod:`.segments`), look-ahead (:mod:`.lookahead`), jerk-limited
or trapezoidal profiles (:mod:`.profiles`), the phase table and its sampling (:mod:`.phases`),
standstill (:mod:`.standstill`). The entrance is the streaming planner :func:`iter_motion`
(:mod:`.stream`, bounded chunks); :func:`plan` (:mod:`.trajectory`) plans a whole program at
once. Its output is :class:`Motion` (:mod:`.motion`), also built from sampled positions
(:mod:`.fromsamples`). :func:`iter_nodes` (:mod:`.nodes`) gives the motion at the
quadrature nodes of the planned phases instead of on a sample grid.
"""
from .fromsamples import motion_from_samples
from .motion import Motion
from .nodes import gauss_legendre, iter_nodes, iter_window_motions, NodeChunk, WindowMotion
from .segments import line_speed_limits
from .standstill import grid_interval_counts
from .stream import DEFAULT_CHUNK_SAMPLES, estimate_plan, grid_samples, iter_motion, iter_plan
from .trajectory import plan

__all__ = [
    'DEFAULT_CHUNK_SAMPLES', 'estimate_plan', 'gauss_legendre', 'grid_interval_counts',
    'grid_samples',
    'iter_motion', 'iter_nodes', 'iter_plan', 'iter_window_motions', 'line_speed_limits', 'Motion',
    'motion_from_samples', 'NodeChunk', 'plan', 'WindowMotion',
]
