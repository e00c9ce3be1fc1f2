"""Every report page a test writes is rendered in headless Chromium after the test.

A test that leaves a report (``index.html`` beside the report marker) in its ``tmp_path``
fails at teardown if a table overflows its container, an image does not load or the page
scrolls sideways, at each width of :data:`report_browser.WIDTHS`. Without Chromium nothing is
rendered here and ``test/report/test_browser.py`` skips with a message; ``FAE_BROWSER=0``
turns the check off.

Skips for a missing dependency (LinuxCNC, rclpy, Chromium, the shared data) go through
``test/must_run.py``; with ``FAE_MUST_RUN`` set (``.ci/run``) the hooks below turn those of
the listed dependencies into failures.
"""
from __future__ import annotations

import os

import must_run
import pytest
from report_browser import chromium, problems

from feed_axis_energy.outputs import REPORT_MARKER


@pytest.fixture(autouse=True)
def _report_pages_render_in_a_browser(request):
    wanted = ('tmp_path' in request.fixturenames and os.environ.get('FAE_BROWSER') != '0'
              and chromium() is not None)
    tmp = request.getfixturevalue('tmp_path') if wanted else None
    yield
    if tmp is None:
        return
    bad = []
    for page in sorted(tmp.rglob('index.html')):
        if (page.parent / REPORT_MARKER).is_file():
            bad += problems(page)
    if bad:
        pytest.fail('report pages do not render well in Chromium:\n' + '\n'.join(bad))


def pytest_configure(config):
    try:
        must_run.required()
    except ValueError as exc:
        raise pytest.UsageError(str(exc)) from None


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    must_run.enforce(report)
    return report


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector):
    report = yield
    must_run.enforce(report)
    return report
