"""Progress lines: silent for short jobs, quarters in logs, nothing under --quiet."""
import io

from feed_axis_energy.cli.progress import Progress


def test_log_stream_gets_a_line_per_quarter_and_ends_at_100() -> None:
    out = io.StringIO()
    p = Progress('job', delay_s=0.0, stream=out)
    for i in range(101):
        p(i / 100)
    p.done()
    assert out.getvalue().splitlines() == [f'[job] {v:3d} %' for v in (0, 25, 50, 75, 100)]


def test_disabled_and_short_jobs_print_nothing() -> None:
    out = io.StringIO()
    quiet = Progress('job', enabled=False, delay_s=0.0, stream=out)
    short = Progress('job', delay_s=60.0, stream=out)
    for p in (quiet, short):
        p(0.5)
        p.done()
    assert out.getvalue() == ''
