"""G-code text through the parser and the planner: ``parse_gcode`` -> ``plan`` -> checks.

Expected values come from the program text (positions, radii, times in the G-code's own
units) and hand calculations, never from the planner's output.
"""
import math
import re

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.machine.limits import AxisLimits, PlannerOptions
from feed_axis_energy.plan.trajectory import plan

LIM = {'X': AxisLimits(0.5, 3.0, 60.0), 'Y': AxisLimits(0.5, 3.0, 60.0),
       'Z': AxisLimits(0.4, 2.5, 40.0)}
T = 1e-3
_MOTION_WORD = re.compile(r'\b[GgMm]0*[0-4]\b|[XYZxyz]\s*[-+.\d]')


def _run(text, **options):
    prog = parse_gcode(text, file='prog.nc')
    return prog, plan(prog, LIM, options=PlannerOptions(**options))


def _speed(m):
    return np.linalg.norm(m.vel, axis=1)


def _line_samples(m, line):
    return np.nonzero(m.line == line)[0]


CONTOUR = """\
(pocket outline with rounded corners, one Z arc and a dwell)
G21 G90 G94 G17 G64
G0 X10 Y0 Z5
G1 Z-1 F600
G1 X50 F3000
G3 X60 Y10 I0 J10
G1 Y30
G2 X50 Y40 R10
G4 P0.5
G1 X10
G18 G2 X0 Z9 I-10 K0
G17 G1 Y10 F1200
M30
"""


def test_end_position_and_lines_of_a_contour():
    prog, m = _run(CONTOUR)
    lines = CONTOUR.splitlines()
    assert_allclose(m.pos[-1], [0.0, 0.010, 0.009], atol=1e-12)
    assert_allclose(m.pos[0], [0.0, 0.0, 0.0], atol=0)
    assert_allclose(m.vel[[0, -1]], 0.0, atol=1e-12)
    # every sample names a line of the text that moves (or dwells) the axes
    used = np.unique(m.line)
    assert used.min() >= 1 and used.max() <= len(lines)
    for ln in used:
        assert _MOTION_WORD.search(lines[ln - 1]), (ln, lines[ln - 1])
    # each motion line of the program gets samples, in program order
    motion_lines = [i for i, text in enumerate(lines, 1)
                    if _MOTION_WORD.search(text) and not text.startswith('M30')]
    assert list(used) == motion_lines
    assert np.all(np.diff(m.line) >= 0)
    # the samples of the G3 line lie on its circle (centre X50 Y10, radius 10 mm)
    on_arc = _line_samples(m, 6)
    assert_allclose(np.hypot(m.pos[on_arc, 0] - 0.05, m.pos[on_arc, 1] - 0.01), 0.01,
                    atol=1e-12)


def test_dwell_takes_its_time_at_rest():
    _, m = _run(CONTOUR)
    rest = _line_samples(m, 9)
    # 0.5 s at 1 kHz: 500 samples, give or take the one the junction rounds to
    assert abs(rest.size - 500) <= 1
    assert_allclose(m.vel[rest], 0.0, atol=0)
    assert_allclose(m.pos[rest], [[0.05, 0.04, -0.001]] * rest.size, atol=1e-12)


@pytest.mark.parametrize('plane, text, centre, axes', [
    (17, 'G17 G2 X10 Y10 I0 J10', (0.0, 0.01), (0, 1)),
    (18, 'G18 G3 X10 Z10 I0 K10', (0.0, 0.01), (0, 2)),
    (19, 'G19 G2 Y10 Z10 J0 K10', (0.0, 0.01), (1, 2)),
])
def test_arcs_in_each_plane(plane, text, centre, axes):
    prog, m = _run(f'G21 G90\n{text} F1200\n')
    a, b = axes
    r = np.hypot(m.pos[:, a] - centre[0], m.pos[:, b] - centre[1])
    assert_allclose(r, 0.01, atol=1e-12)
    other = 3 - a - b
    assert_allclose(m.pos[:, other], 0.0, atol=0)
    assert_allclose(m.pos[-1, [a, b]], [0.01, 0.01], atol=1e-12)
    # quarter circles: the length over the feed (20 mm/s) is a lower bound of the time
    assert m.duration_s > 0.5 * math.pi * 0.01 / 0.02


def test_arc_directions_in_the_zx_plane():
    # G18 looks down +Y: X is the second, Z the first in-plane axis; from X10 to Z10 around
    # the origin a G3 goes the long way (270 degrees) and a G2 the short way (90 degrees)
    _, ccw = _run('G21 G90 G0 X10\nG18 G3 X0 Z10 I-10 K0 F1200\n')
    _, cw = _run('G21 G90 G0 X10\nG18 G2 X0 Z10 I-10 K0 F1200\n')
    assert np.min(ccw.pos[:, 2]) < -0.0099 and np.min(cw.pos[:, 2]) > -1e-12
    assert ccw.duration_s > 2.5 * cw.duration_s


def test_exact_stop_g61_and_blending_g64():
    body = 'G1 X20 F6000\nG1 X40 Y2\nG1 X60 Y0\n'
    _, stop = _run('G21 G90 G61\n' + body, corner_tolerance_m=1e-4)
    _, blend = _run('G21 G90 G64\n' + body, corner_tolerance_m=1e-4)
    for x, y in ((0.02, 0.0), (0.04, 0.002)):
        at = np.argmin(np.hypot(stop.pos[:, 0] - x, stop.pos[:, 1] - y))
        # rest at the block end: within one sample of a jerk ramp from zero speed
        assert _speed(stop)[at] <= 60.0 * T * T
        at_b = np.argmin(np.abs(blend.pos[:, 0] - x))
        # passed at speed: the velocity-step rule allows a T / |du_y| = 0.030 and 0.015 m/s
        assert _speed(blend)[at_b] > 0.01
    assert blend.duration_s < stop.duration_s
    assert_allclose(stop.pos[-1], blend.pos[-1], atol=1e-12)
    # G9 stops a single block under G64
    _, g9 = _run('G21 G90 G64\nG1 X20 F6000 G9\nG1 X40 Y2\nG1 X60 Y0\n')
    at = np.argmin(np.hypot(g9.pos[:, 0] - 0.02, g9.pos[:, 1]))
    assert _speed(g9)[at] <= 60.0 * T * T
    at = np.argmin(np.hypot(g9.pos[:, 0] - 0.04, g9.pos[:, 1] - 0.002))
    assert _speed(g9)[at] > 0.01


def test_incremental_g91_and_inches_g20():
    _, inc = _run('G21 G91\nG1 X10 Y5 F1200\nX10\nY-5 Z2\nG2 X10 Y0 I5 J0\n')
    assert_allclose(inc.pos[-1], [0.030, 0.0, 0.002], atol=1e-12)
    _, inch = _run('G20 G90\nG1 X1 Y2 F60\nG91 G1 Z-0.5\n')
    assert_allclose(inch.pos[-1], [0.0254, 0.0508, -0.0127], atol=1e-12)
    # F60 in/min = 25.4 mm/s path speed on the XY line
    assert_allclose(_speed(inch).max(), 0.0254, rtol=1e-9)


def test_inverse_time_g93_takes_the_programmed_time():
    # three collinear blocks at the same speed (10 mm/s, so no ramp inside the middle one);
    # the middle one's F20 means 60/20 = 3 s for its 30 mm, the others' F60 1 s for 10 mm
    text = 'G21 G90 G93\nG1 X10 F60\nG1 X40 F20\nG1 X50 F60\nG94\n'
    _, m = _run(text)
    middle = _line_samples(m, 3)
    assert_allclose(middle.size * T, 3.0, atol=2 * T)
    # the path speed there is the one that meets the time: 30 mm / 3 s
    inner = middle[50:-50]
    assert_allclose(_speed(m)[inner], 0.01, rtol=1e-6)
    assert_allclose(m.pos[-1], [0.05, 0, 0], atol=1e-12)


def test_inverse_time_limited_by_the_machine():
    # 300 mm in 60/200 = 0.3 s would be 1 m/s: the X limit of 0.5 m/s applies instead
    _, m = _run('G21 G90 G93\nG1 X300 F200\n')
    assert m.duration_s > 0.3 / 0.5 * 1.0
    assert _speed(m).max() <= 0.5 * (1 + 1e-12)


def test_cam_polyline_reaches_the_programmed_feed():
    """A full circle of R 30 mm as 360 G1 chords of 0.52 mm (1 deg corners) at F6000.

    One chord from rest could reach only ~0.04 m/s with zero acceleration at both ends, but
    the corners allow a_k T / |du| >= 3e-3 / (2 sin 0.5 deg) = 0.17 m/s, so the chords form
    one group whose acceleration keeps at least a quarter of the path limit (>= 3 m/s^2):
    the time on the circle is at most L / F + F / 0.75 + 0.75 / 60 (one rest-to-rest
    S-curve at that acceleration and the path jerk limit >= 60 m/s^3).
    """
    r, n, feed = 30.0, 360, 0.1
    pts = [(r * math.cos(2 * math.pi * i / n), r * math.sin(2 * math.pi * i / n))
           for i in range(n + 1)]
    text = ['G21 G90 G94 G17 G64', f'G0 X{pts[0][0]:.4f} Y0', f'G1 F{feed * 60000:.0f}']
    text += [f'G1 X{x:.4f} Y{y:.4f}' for x, y in pts[1:]]
    text.append('M30')
    _, m = _run('\n'.join(text) + '\n', corner_tolerance_m=1e-4)
    length = 2 * n * r * math.sin(math.pi / n) * 1e-3
    speed = _speed(m)
    on_circle = m.line >= 4
    assert_allclose(m.pos[-1], [0.03, 0.0, 0.0], atol=1e-7)
    # most of the circle at the feed: the ~2 s on it hold 360 corner samples (the mean of the
    # in and out velocities, slower) and the two ramps of ~0.15 s
    assert np.mean(np.abs(speed[on_circle] - feed) < 1e-6) > 0.6
    assert speed[on_circle].max() <= feed * (1 + 1e-9)
    t_circle = np.count_nonzero(on_circle) * T
    assert length / feed <= t_circle <= length / feed + feed / 0.75 + 0.75 / 60.0 + T
    assert list(np.unique(m.line[on_circle])) == list(range(4, 4 + n))
