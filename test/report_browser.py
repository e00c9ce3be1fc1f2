"""Render a report page in headless Chromium and check its layout from inside the page.

A copy of the page with a small script is loaded with ``--dump-dom``; the script runs after
the load event and writes what it found into the DOM as JSON: every table wider than the
element that holds it (or reaching beyond the window), every image that did not load, and
whether the page scrolls sideways. ``chromium()`` is None where no Chromium is installed.
"""
from __future__ import annotations

import html
import json
import os
from pathlib import Path
import re
import shutil
import subprocess
import tempfile

WIDTHS = tuple(int(w) for w in os.environ.get('FAE_BROWSER_WIDTHS', '1400,800').split(','))
"""Window widths [px] every page is checked at (env ``FAE_BROWSER_WIDTHS``)."""

_SCRIPT = """
<script>
window.addEventListener('load', function () {
  var out = {tables: 0, overflow: [], images: 0, broken: [], page_overflow: false, width: 0};
  out.width = window.innerWidth;
  document.querySelectorAll('table').forEach(function (t, i) {
    out.tables += 1;
    var box = t.parentElement;
    var w = t.getBoundingClientRect();
    var first = (t.querySelector('th, td') || {textContent: ''}).textContent.slice(0, 40);
    if (w.width > box.clientWidth + 1 || w.right > window.innerWidth + 1) {
      out.overflow.push('table ' + i + ' (' + first + '): ' + Math.round(w.width)
                        + ' px in ' + box.clientWidth + ' px');
    }
  });
  document.querySelectorAll('img').forEach(function (im, i) {
    out.images += 1;
    if (!im.complete || im.naturalWidth === 0) {
      out.broken.push('image ' + i + ' (' + (im.alt || '').slice(0, 40) + ')');
    }
  });
  out.page_overflow = document.documentElement.scrollWidth > window.innerWidth + 1;
  var pre = document.createElement('pre');
  pre.id = 'fae-browser-check';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>
"""


def chromium() -> str | None:
    """The Chromium executable, or None."""
    for name in ('chromium', 'chromium-browser', 'google-chrome'):
        found = shutil.which(name)
        if found:
            return found
    return None


def check_page(page: Path, *, width: int, timeout_s: float = 90.0) -> dict:
    """Load ``page`` at ``width`` px and return the script's findings.

    The page is copied, with the script, into a hidden file beside it (relative image paths
    keep working) and the copy is removed afterwards.

    Raises
    ------
    RuntimeError
        No Chromium, or Chromium did not produce the findings.
    """
    exe = chromium()
    if exe is None:
        raise RuntimeError('chromium not installed')
    text = page.read_text(encoding='utf-8')
    probe = page.with_name(f'.browser-check-{os.getpid()}-{page.name}')
    probe.write_text(text.replace('</body>', _SCRIPT + '</body>'), encoding='utf-8')
    profile = tempfile.mkdtemp(prefix='fae-chromium-')
    try:
        proc = subprocess.run(
            [exe, '--headless', '--no-sandbox', '--disable-gpu', '--disable-extensions',
             '--no-first-run', f'--user-data-dir={profile}', '--hide-scrollbars',
             f'--window-size={width},1000', '--virtual-time-budget=10000', '--dump-dom',
             probe.as_uri()],
            capture_output=True, text=True, timeout=timeout_s)
    finally:
        probe.unlink(missing_ok=True)
        shutil.rmtree(profile, ignore_errors=True)
    found = re.search(r'<pre id="fae-browser-check">(.*?)</pre>', proc.stdout, re.S)
    if not found:
        msg = (f'chromium gave no result for {page} (exit {proc.returncode}): '
               f'{proc.stderr[-400:]}')
        raise RuntimeError(msg)
    return json.loads(html.unescape(found.group(1)))


def problems(page: Path, *, widths: tuple[int, ...] = WIDTHS) -> list[str]:
    """Every layout problem of ``page`` at the given widths (empty: it renders well)."""
    out = []
    for width in widths:
        r = check_page(page, width=width)
        where = f'{page} at {width} px'
        out += [f'{where}: {t} overflows its container' for t in r['overflow']]
        out += [f'{where}: {b} did not load' for b in r['broken']]
        if r['page_overflow']:
            out.append(f'{where}: the page scrolls sideways')
    return out
