"""Plot-ready topics: read as Foxglove and PlotJuggler read them, compared with the simulation.

Viewers take one value per field per message, at the message's log time (= header stamp);
they decode with the schema stored in the MCAP file. PlotJuggler's ROS 2 JointState parser
(plotjuggler-ros-plugins, ``plugins/ros2_parsers/jointstates_msg.h``) makes one series
``<topic>/<name>/<field>`` per name and filled field, one point per message, as
:func:`_as_a_viewer_reads` does. The test does the same with the mcap
library (raw records, the embedded schema text registered in an empty rosbags typestore),
and checks that every plotted power is the simulated power at its stamp and that the peaks
(maximum and minimum of every power column) are plotted.
"""
from pathlib import Path

from mcap.reader import make_reader
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, get_types_from_msg, Stores

from feed_axis_energy.record import bagio
from feed_axis_energy.record.bagio import typestore
from feed_axis_energy.errors import DataError
from feed_axis_energy.gcode.load import load_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.record.plotread import read_plot_topic
from feed_axis_energy.record.plottopics import (JOINT_STATE, joint_state_rows, PlotDecimator,
                                                TOPIC_PLOT_AXES, TOPIC_PLOT_BLOCK_ENERGY,
                                                TOPIC_PLOT_POWER)
from feed_axis_energy.record.recording import SimulationBagWriter
from feed_axis_energy.sim.stream import simulate_stream
from feed_axis_energy.sim.simulate import simulate_program

REPO = Path(__file__).resolve().parents[2]
_NS = 1_000_000_000

CASES = {
    'contour': ('three_axis_mill.yaml', 'three_axis_contour.nc'),
    'demonstrator': ('demonstrator.yaml', 'demonstrator_f500.nc'),   # 1 s dwells
}


# ---------------------------------------------------------------- message bytes
@pytest.mark.parametrize('names', [('X', 'total'), ('X', 'Y', 'Zed', 'total'), ()])
@pytest.mark.parametrize('filled', [(True, True, False), (True, True, True),
                                    (False, False, False)])
@pytest.mark.parametrize('frame_id', ['', 'abc'])
@pytest.mark.parametrize('lead', [0, 31])
def test_joint_state_rows_equal_rosbags(names, filled, frame_id, lead):
    rng = np.random.default_rng(1)
    t_ns = np.array([0, 1_500_000_000, 1_779_000_000_000_000_001])
    k = len(names)
    fields = [rng.normal(size=(3, k)) if f else None for f in filled]
    rows = joint_state_rows(t_ns, names, fields, frame_id=frame_id, lead=lead)
    store = typestore()
    cls = store.types[JOINT_STATE]
    header = store.types['std_msgs/msg/Header']
    time = store.types['builtin_interfaces/msg/Time']
    empty = np.zeros(0)
    for i in range(3):
        values = [empty if f is None else f[i] for f in fields]
        msg = cls(header=header(stamp=time(sec=int(t_ns[i] // _NS), nanosec=int(t_ns[i] % _NS)),
                                frame_id=frame_id),
                  name=list(names), position=values[0], velocity=values[1], effort=values[2])
        want = bytes(store.serialize_cdr(msg, JOINT_STATE))
        assert rows.rows[i, rows.start:rows.start + rows.length].tobytes() == want


# ---------------------------------------------------------------- the selection rule
def test_decimator_by_hand():
    # 10 samples at 10 Hz, display at 2 Hz: intervals [0, 0.5) and [0.5, 1.0) of 5 samples
    t = np.arange(10) / 10
    power = np.array([1., 5., 2., -3., 0., 0., 0., 7., 7., -1.])
    dec = PlotDecimator(rate_hz=2, keys=[0])
    got_t, got_v = dec.push(t, power[:, None])
    # the second interval may continue: only the first is complete
    assert got_t.tolist() == [0.0, 0.1, 0.3]          # first, max 5 at 0.1, min -3 at 0.3
    rest_t, rest_v = dec.finish()
    assert rest_t.tolist() == [0.5, 0.7, 0.9]         # first, first max 7 at 0.7, min -1
    assert rest_v[:, 0].tolist() == [0.0, 7.0, -1.0]


def test_decimator_full_rate_keeps_everything():
    t = np.arange(7) / 1000
    v = np.arange(14.0).reshape(7, 2)
    got_t, got_v = PlotDecimator(rate_hz=0, keys=[0]).push(t, v)
    assert got_t is t and got_v is v


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_decimator_independent_of_chunks_and_keeps_extremes(seed):
    rng = np.random.default_rng(seed)
    n = 5000
    t = np.arange(n) / 1000
    v = rng.normal(size=(n, 3)).round(1)               # ties inside intervals
    whole = PlotDecimator(rate_hz=7, keys=[0, 2])
    wt, wv = whole.push(t, v)
    ft, fv = whole.finish()
    want_t = np.concatenate((wt, ft))
    cuts = np.sort(rng.choice(np.arange(1, n), size=20, replace=False))
    dec = PlotDecimator(rate_hz=7, keys=[0, 2])
    parts = [dec.push(t[a:b], v[a:b]) for a, b in zip(np.r_[0, cuts], np.r_[cuts, n])]
    parts.append(dec.finish())
    got_t = np.concatenate([p[0] for p in parts])
    np.testing.assert_array_equal(got_t, want_t)
    # every interval: its first sample and each key column's extremes are kept
    k = np.floor(t * 7 + 1e-9).astype(int)
    kept = set(np.searchsorted(t, want_t).tolist())
    for g in np.unique(k):
        rows = np.flatnonzero(k == g)
        assert rows[0] in kept
        for c in (0, 2):
            col = v[rows, c]
            assert rows[np.argmax(col)] in kept and rows[np.argmin(col)] in kept
        assert not any(r in kept for r in rows if v[r, 0] not in (v[rows, 0].max(),
                                                                  v[rows, 0].min())
                       and v[r, 2] not in (v[rows, 2].max(), v[rows, 2].min())
                       and r != rows[0])


def test_decimator_refuses_bad_rate():
    with pytest.raises(ValueError, match='display rate'):
        PlotDecimator(rate_hz=float('nan'), keys=[])


# ---------------------------------------------------------------- recordings
def _simulate_and_record(out: Path, case: str, *, plot_rate_hz: float,
                         chunk_samples: int = 1234, start_ns: int = 0):
    machine_file, program = CASES[case]
    machine = load_machine(REPO / 'config' / machine_file)
    prog = load_gcode(REPO / 'config' / 'programs' / program, home=machine.home_point())
    rate = machine.planner.options().rate_hz
    with SimulationBagWriter(out, compression='zstd', plot_rate_hz=plot_rate_hz,
                             rate_hz=rate, start_ns=start_ns) as writer:
        summary, blocks = simulate_stream(prog.moves, machine, file=prog.file,
                                          chunk_samples=chunk_samples, on_chunk=writer.write,
                                          chunk_gaps=True)
        writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
    return simulate_program(prog, machine), blocks


def _as_a_viewer_reads(bag: Path, topic: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``(log times [ns], {'<name>/<field>': values})`` as Foxglove/PlotJuggler plot them.

    The mcap library gives the records; the message is decoded with the schema stored in
    the file (not our typestore); each field of each name is one value of one series.
    """
    (path,) = bag.glob('*.mcap')
    times, series = [], {}
    store = get_typestore(Stores.EMPTY)
    with open(path, 'rb') as fh:
        reader = make_reader(fh, validate_crcs=True)
        for schema, channel, message in reader.iter_messages(topics=[topic],
                                                             log_time_order=True):
            if schema.name not in store.types:
                store.register(get_types_from_msg(schema.data.decode(), schema.name))
            msg = store.deserialize_cdr(message.data, schema.name)
            stamp = msg.header.stamp.sec * _NS + msg.header.stamp.nanosec
            assert stamp == message.log_time == message.publish_time
            times.append(message.log_time)
            for field in ('position', 'velocity', 'effort'):
                values = getattr(msg, field)
                assert len(values) in (0, len(msg.name))      # one value per name
                for name, value in zip(msg.name, values):
                    series.setdefault(f'{name}/{field}', []).append(float(value))
    n = len(times)
    assert all(len(v) == n for v in series.values())
    return np.array(times, np.int64), {k: np.array(v) for k, v in series.items()}


@pytest.mark.parametrize('case', list(CASES))
@pytest.mark.parametrize('plot_rate_hz', [20.0, 3.0])
def test_plotted_power_is_the_simulated_power_peak_included(tmp_path, case, plot_rate_hz):
    bag = tmp_path / 'rec'
    whole, _ = _simulate_and_record(bag, case, plot_rate_hz=plot_rate_hz)
    t_ns, series = _as_a_viewer_reads(bag, TOPIC_PLOT_POWER)
    assert np.all(np.diff(t_ns) > 0)
    pw = whole.power
    rate = round(1 / np.median(np.diff(pw.t)))
    idx = np.rint(t_ns / _NS * rate).astype(int)
    np.testing.assert_allclose(pw.t[idx] * _NS, t_ns, atol=1)
    columns = list(pw.axes) + ['total']
    simulated = np.column_stack((pw.power_w, pw.total_w))
    energy = np.column_stack((pw.energy_j, pw.total_energy_j))
    for j, name in enumerate(columns):
        plotted = series[f'{name}/velocity']
        np.testing.assert_array_equal(plotted, simulated[idx, j])
        # the peaks: the largest and smallest power of the whole program are plotted
        assert plotted.max() == simulated[:, j].max()
        assert plotted.min() == simulated[:, j].min()
        np.testing.assert_allclose(series[f'{name}/position'], energy[idx, j], rtol=1e-12,
                                   atol=1e-9)
    # every display interval shows at least its first sample, but those inside a standstill
    # (recorded at 1 Hz, every value constant and energy linear: nothing to see there)
    shown = set(np.floor(t_ns / _NS * plot_rate_hz + 1e-9).astype(int).tolist())
    interval = np.floor(pw.t * plot_rate_hz + 1e-9).astype(int)
    for g in sorted(set(range(interval[-1] + 1)) - shown):
        rows = np.flatnonzero(interval == g)
        assert rows[0] > 0 and np.all(simulated[rows] == simulated[rows[0] - 1]), g
    if case == 'contour':                                         # no standstill there
        assert shown == set(range(interval[-1] + 1))
    # far fewer messages than samples at a display rate
    assert t_ns.shape[0] < pw.t.shape[0] / 5


def test_axes_topic_torque_and_speed(tmp_path):
    bag = tmp_path / 'rec'
    whole, _ = _simulate_and_record(bag, 'contour', plot_rate_hz=10.0)
    t_ns, series = _as_a_viewer_reads(bag, TOPIC_PLOT_AXES)
    dyn = whole.dynamics
    idx = np.rint(t_ns / 1e6).astype(int)                       # 1 kHz grid
    for j, axis in enumerate(whole.motion.axes):
        torque = series[f'{axis}/effort']
        np.testing.assert_array_equal(torque, dyn.torque_nm[idx, j])
        np.testing.assert_array_equal(series[f'{axis}/velocity'], dyn.omega_rad_s[idx, j])
        np.testing.assert_array_equal(series[f'{axis}/position'], dyn.angle_rad[idx, j])
        assert torque.max() == dyn.torque_nm[:, j].max()
        assert torque.min() == dyn.torque_nm[:, j].min()


def test_full_rate_plots_every_recorded_sample(tmp_path):
    bag = tmp_path / 'rec'
    _simulate_and_record(bag, 'demonstrator', plot_rate_hz=0)
    recorded = bagio.read_series(bag, bagio.TOPIC_POWER)
    plot = read_plot_topic(bag, TOPIC_PLOT_POWER)
    np.testing.assert_array_equal(plot.t_ns, np.rint(recorded.t * _NS).astype(np.int64))
    np.testing.assert_array_equal(plot.velocity, recorded.velocities)
    np.testing.assert_array_equal(plot.position, recorded.positions)
    assert plot.effort is None


def test_block_energy_as_numbers_and_readers_agree(tmp_path):
    bag = tmp_path / 'rec'
    _simulate_and_record(bag, 'contour', plot_rate_hz=20.0)
    want = bagio.read_block_energy(bag)
    plot = read_plot_topic(bag, TOPIC_PLOT_BLOCK_ENERGY)
    assert plot.t_ns.shape == (1,)
    assert [int(n) for n in plot.names] == [line for line, _, _ in want]
    np.testing.assert_array_equal(plot.position[0], [e for _, e, _ in want])
    np.testing.assert_array_equal(plot.effort[0], [d for _, _, d in want])
    mean = [e / d if d > 0 else 0.0 for _, e, d in want]
    np.testing.assert_allclose(plot.velocity[0], mean, rtol=1e-15)
    # rosbags' AnyReader sees the same counts as the metadata
    with AnyReader([bag], default_typestore=typestore()) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        for topic in (TOPIC_PLOT_POWER, TOPIC_PLOT_AXES, TOPIC_PLOT_BLOCK_ENERGY):
            conns = [c for c in reader.connections if c.topic == topic]
            assert sum(1 for _ in reader.messages(connections=conns)) == counts[topic] > 0
    assert bagio.bag_topics(bag)[TOPIC_PLOT_POWER][0] == JOINT_STATE


def test_read_plot_topic_names_the_place(tmp_path):
    bag = tmp_path / 'rec'
    _simulate_and_record(bag, 'contour', plot_rate_hz=20.0)
    with pytest.raises(DataError, match='not in bag'):
        read_plot_topic(bag, '/plot/nothing')
    with pytest.raises(DataError, match='expected sensor_msgs/msg/JointState'):
        read_plot_topic(bag, bagio.TOPIC_POWER)


# ---------------------------------------------------------------- the node graph's recorder
@pytest.mark.parametrize('plot_rate_hz', [20.0, 0.0])
def test_graph_plotter_writes_what_simulate_out_writes(tmp_path, plot_rate_hz):
    """Batches of the graph's power / axis_state streams give the offline plot messages."""
    from feed_axis_energy.graph.plots import GraphPlotter
    from feed_axis_energy.record.recording import simulation_series
    bag = tmp_path / 'rec'
    machine_file, program = CASES['contour']
    machine = load_machine(REPO / 'config' / machine_file)
    prog = load_gcode(REPO / 'config' / 'programs' / program, home=machine.home_point())
    whole = simulate_program(prog, machine)
    start = 1_795_442_400 * _NS
    with SimulationBagWriter(bag, plot_rate_hz=plot_rate_hz, standstill_period_s=None,
                             start_ns=start) as writer:
        writer.write(whole)
        writer.finish([], summary={}, stamp_s=float(whole.power.t[-1]))
    plotter = GraphPlotter(rate_hz=plot_rate_hz, start_ns=start)
    got = []
    series = simulation_series(whole)
    for topic, key in (('power', bagio.TOPIC_POWER), ('axis_state', bagio.TOPIC_AXIS_STATE)):
        s = series[key]
        t_ns = np.rint(s.t * _NS).astype(np.int64)
        for lo in range(0, t_ns.shape[0], 100):
            fields = {f: None if getattr(s, f) is None else getattr(s, f)[lo:lo + 100]
                      for f in ('positions', 'velocities', 'accelerations', 'effort')}
            got += plotter.add(topic, t_ns[lo:lo + 100], s.names, fields)
    got += plotter.finish()
    for topic in (TOPIC_PLOT_POWER, TOPIC_PLOT_AXES):
        mine = [(m[1], m[2]) for m in got if m[0] == topic]
        (path,) = bag.glob('*.mcap')
        with open(path, 'rb') as fh:
            want = [(m.log_time, m.data) for _, _, m in
                    make_reader(fh).iter_messages(topics=[topic], log_time_order=True)]
        assert len(mine) == len(want) > 0
        assert mine == want


def test_graph_plotter_refuses_other_joint_names():
    from feed_axis_energy.graph.plots import GraphPlotter
    plotter = GraphPlotter(rate_hz=20)
    ones = np.ones((3, 2))
    plotter.add('power', np.arange(3), ('X', 'total'), {'positions': ones, 'velocities': ones})
    with pytest.raises(DataError, match='differ'):
        plotter.add('power', np.arange(3, 6), ('Y', 'total'),
                    {'positions': ones, 'velocities': ones})
    with pytest.raises(DataError, match='without velocities'):
        plotter.add('power', np.arange(3, 6), ('X', 'total'),
                    {'positions': ones, 'velocities': None})


def test_restamp():
    from feed_axis_energy.graph.flow import header_stamp_ns
    from feed_axis_energy.record.starttime import restamp
    rows = joint_state_rows(np.array([1_500_000_000]), ('X',), [np.ones((1, 1)), None, None])
    data = rows.rows[0, rows.start:rows.start + rows.length].tobytes()
    new = restamp(data, 1_795_442_400 * _NS + 7)
    assert header_stamp_ns(new) == 1_795_442_400 * _NS + 7
    assert new[:4] == data[:4] and new[12:] == data[12:]
    with pytest.raises(DataError):
        restamp(data[:8], 0)
    with pytest.raises(DataError):
        restamp(data, 2 ** 31 * _NS)


@pytest.mark.parametrize('seed', [3, 4, 5, 6])
def test_decimator_matches_a_brute_force_selection_on_irregular_times(seed):
    rng = np.random.default_rng(seed)
    # 1 kHz with holes (a standstill recorded at 1 Hz) and ties
    t = np.sort(rng.choice(np.arange(20_000), size=6000, replace=False)) / 1000
    v = rng.integers(-3, 4, size=(t.shape[0], 3)).astype(float)
    dec = PlotDecimator(rate_hz=20, keys=[0, 2])
    parts = [dec.push(t[a:b], v[a:b]) for a, b in ((0, 1000), (1000, 1001), (1001, 6000))]
    parts.append(dec.finish())
    got = np.concatenate([p[0] for p in parts])
    k = np.floor(t * 20 + 1e-9).astype(int)
    want = set()
    for g in np.unique(k):
        rows = np.flatnonzero(k == g)
        want.add(rows[0])
        for c in (0, 2):
            want.add(rows[np.argmax(v[rows, c])])
            want.add(rows[np.argmin(v[rows, c])])
    np.testing.assert_array_equal(got, t[sorted(want)])
