"""Rows of live samples: stamp order, and every odd sample counted (measured/live/rows.py)."""
import pytest

from feed_axis_energy.measured.live import RowAssembler

SLOTS = (('X', 'power_w'), ('Y', 'power_w'))
MS = 1_000_000


def feed(asm, samples):
    rows = []
    for axis, stamp_ms, value in samples:
        rows.extend(asm.add(axis, 'power_w', stamp_ms * MS, value))
    return rows


def test_rows_leave_complete_and_in_stamp_order():
    asm = RowAssembler(SLOTS, reorder_s=0.5)
    rows = feed(asm, [('X', 0, 1.0), ('Y', 0, 2.0), ('X', 100, 3.0), ('Y', 100, 4.0)])
    assert [r.stamp_ns for r in rows] == [0, 100 * MS]
    assert rows[1].values.tolist() == [3.0, 4.0]
    assert asm.counters.rows == 2 and asm.counters.accepted == 4


def test_out_of_order_samples_are_used_and_counted():
    asm = RowAssembler(SLOTS, reorder_s=0.5)
    rows = feed(asm, [('X', 0, 1.0), ('X', 100, 3.0), ('Y', 100, 4.0), ('Y', 0, 2.0)])
    assert [r.stamp_ns for r in rows] == [0, 100 * MS]
    assert rows[0].values.tolist() == [1.0, 2.0]
    assert asm.counters.out_of_order == 1


def test_duplicates_keep_the_first_value():
    asm = RowAssembler(SLOTS, reorder_s=0.5)
    rows = feed(asm, [('X', 0, 1.0), ('X', 0, 9.0), ('Y', 0, 2.0), ('Y', 0, 7.0)])
    assert rows[0].values.tolist() == [1.0, 2.0]
    assert asm.counters.duplicate == 2          # one while pending, one after it left


def test_late_samples_are_counted_not_used():
    asm = RowAssembler(SLOTS, reorder_s=0.2)
    feed(asm, [('X', 0, 1.0), ('Y', 0, 2.0), ('X', 100, 1.0), ('Y', 100, 2.0)])
    assert feed(asm, [('X', 50, 5.0)]) == []
    assert asm.counters.late == 1


def test_a_missing_value_drops_its_row_and_the_gap_is_counted():
    asm = RowAssembler(SLOTS, reorder_s=0.25)
    samples = []
    for k in range(10):
        samples.append(('X', 100 * k, float(k)))
        if k != 4:                               # Y of stamp 400 ms never comes
            samples.append(('Y', 100 * k, float(k)))
    rows = feed(asm, samples) + asm.flush()
    assert [r.stamp_ns // MS for r in rows] == [0, 100, 200, 300, 500, 600, 700, 800, 900]
    assert asm.counters.incomplete == 1
    assert asm.counters.gaps == 1 and asm.counters.missing == 1


def test_a_long_silence_is_one_gap_with_its_missing_samples():
    asm = RowAssembler((('X', 'power_w'),))
    stamps = list(range(0, 1000, 100)) + list(range(2000, 3000, 100))
    feed(asm, [('X', s, 1.0) for s in stamps])
    assert asm.counters.gaps == 1 and asm.counters.missing == 10   # 1000 ... 1900 ms


def test_pending_rows_are_bounded():
    asm = RowAssembler(SLOTS, reorder_s=1e6, max_pending=100)
    feed(asm, [('X', k, 1.0) for k in range(10_000)])        # Y never comes
    assert asm.pending <= 100
    assert asm.counters.overflow == 10_000 - 100


@pytest.mark.parametrize('bad', [0.0 - 1.0, float('nan')])
def test_bad_options_are_refused(bad):
    with pytest.raises(ValueError):
        RowAssembler(SLOTS, reorder_s=bad)
