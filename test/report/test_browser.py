"""The Chromium check itself: it finds an overflowing table, a broken image, a wide page.

Every report the suite writes is checked by ``test/conftest.py``; these tests show that the
check can fail, and skip with a message where Chromium is absent.
"""
from __future__ import annotations

from pathlib import Path

import must_run
from report_browser import check_page, chromium, problems

pytestmark = must_run.skipif(
    'chromium', chromium() is None, 'Chromium not installed (Debian package chromium): report '
                                    'pages are not rendered in a browser')

_PNG = ('data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk'
        '+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg==')


def _page(tmp_path: Path, body: str) -> Path:
    page = tmp_path / 'page.html'
    page.write_text('<!DOCTYPE html><html><head><meta charset="utf-8"><style>'
                    'body { max-width: 600px; margin: 0 auto; } div.fit { overflow-x: auto; }'
                    f'</style></head><body>{body}</body></html>')
    return page


def test_a_page_that_fits_has_no_problems(tmp_path) -> None:
    page = _page(tmp_path, f'<table><tr><td>a</td><td>1 kJ</td></tr></table><img src="{_PNG}">')
    r = check_page(page, width=800)
    assert r['tables'] == 1 and r['images'] == 1
    assert problems(page, widths=(800,)) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ['page.html']    # probe removed


def test_an_overflowing_table_a_broken_image_and_a_wide_page_are_found(tmp_path) -> None:
    wide = ''.join(f'<td style="white-space:nowrap">column number {i}</td>' for i in range(30))
    page = _page(tmp_path, f'<div class="fit"><table><tr>{wide}</tr></table></div>'
                           '<img src="missing.png" alt="gone">'
                           '<div style="width: 3000px">wide</div>')
    found = problems(page, widths=(1000,))
    assert any('table 0 (column number 0)' in p and 'overflows' in p for p in found)
    assert any('image 0 (gone) did not load' in p for p in found)
    assert any('scrolls sideways' in p for p in found)
