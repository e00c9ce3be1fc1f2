"""Numeric CSV tables from outside: the one reader of CSV text for measured runs and trajectories.

Errors are :class:`~feed_axis_energy.errors.DataError` naming the file, the column and the
1-based data row as counted in the file (row 1 is the first line after the header).
"""
from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .errors import DataError, shorten

__all__ = ['BLOCK_ROWS', 'MIN_STEP_S', 'column_values', 'iter_csv_blocks', 'read_csv_table']

MIN_STEP_S = 1.0e-9   # smallest time step between rows: stamps are whole nanoseconds


BLOCK_ROWS = 65_536
"""Data rows per block of :func:`iter_csv_blocks`: bounds the text held at once."""


def iter_csv_blocks(path: Path, *, block_rows: int | None = None
                    ) -> Iterator[tuple[list[str], list[list[str]], np.ndarray]]:
    """Read a CSV file with a header line block by block: memory bounded by the block.

    Empty lines are skipped; every other row must have as many fields as the header. A
    caller converts each block's cells to numbers and lets the text go, so a file of any
    length is never held as text at once.

    Yields
    ------
    header, rows, numbers
        The stripped header cells (the same list every time), up to ``block_rows`` data rows
        as lists of strings, and each row's 1-based data-row number as counted in the file
        (row 1 is the first line after the header). At least one block. ``block_rows``
        defaults to :data:`BLOCK_ROWS`.

    Raises
    ------
    DataError
        The file cannot be read, is not CSV text, is empty, has a header only or a row of the
        wrong width.
    """
    file = str(path)
    block_rows = BLOCK_ROWS if block_rows is None else max(1, int(block_rows))
    try:
        with open(path, newline='', encoding='utf-8-sig') as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                raise DataError('empty file; expected a header line', file=file)
            header = [h.strip() for h in header]
            rows: list[list[str]] = []
            lines: list[int] = []
            seen = False
            for row in reader:
                if not row or (len(row) == 1 and not row[0].strip()):
                    continue
                if len(row) != len(header):
                    msg = f'has {len(row)} fields, the header has {len(header)}'
                    raise DataError(msg, file=file, row=reader.line_num - 1)
                rows.append(row)
                lines.append(reader.line_num - 1)
                if len(rows) == block_rows:
                    seen = True
                    yield header, rows, np.array(lines, dtype=np.int64)
                    rows, lines = [], []
            if rows or not seen:
                if not rows:
                    raise DataError('header only, no data rows', file=file)
                yield header, rows, np.array(lines, dtype=np.int64)
    except OSError as err:
        msg = f'cannot read: {err.strerror or err}'
        raise DataError(msg, file=file) from err
    except (csv.Error, UnicodeDecodeError) as err:
        msg = f'not a readable CSV file: {err}'
        raise DataError(msg, file=file) from err


def read_csv_table(path: Path) -> tuple[list[str], list[list[str]], np.ndarray]:
    """Read a CSV file with a header line: its header, its data rows and their row numbers.

    The whole file at once (:func:`iter_csv_blocks` reads it in bounded blocks). Empty lines
    are skipped; every other row must have as many fields as the header.

    Returns
    -------
    header, rows, numbers
        The stripped header cells, the rows as lists of strings, and each row's 1-based
        data-row number as counted in the file (row 1 is the first line after the header).

    Raises
    ------
    DataError
        The file cannot be read, is not CSV text, is empty or has a row of the wrong width.
    """
    header: list[str] = []
    rows: list[list[str]] = []
    numbers = []
    for header, part, lines in iter_csv_blocks(path):
        rows += part
        numbers.append(lines)
    return header, rows, np.concatenate(numbers)


def column_values(rows: list[list[str]], j: int, numbers: np.ndarray, file: str,
                  name: str) -> np.ndarray:
    """The numbers of column ``j`` (named ``name``) of ``rows``, all finite.

    Raises
    ------
    DataError
        An empty cell, a cell that is not a number, or a non-finite number, naming file,
        column and data row.
    """
    cells = [row[j] for row in rows]
    try:
        values = np.array(cells, dtype=np.float64)
    except ValueError:
        values = None
    if values is not None and np.isfinite(values).all():
        return values
    for i, cell in enumerate(cells):
        text = cell.strip()
        if not text:
            raise DataError('empty cell; expected a number', file=file, column=name,
                            row=int(numbers[i]))
        try:
            value = float(text)
        except ValueError:
            msg = f'{shorten(text)!r} is not a number'
            raise DataError(msg, file=file, column=name, row=int(numbers[i])) from None
        if not np.isfinite(value):
            msg = f'{shorten(text)!r} is not a finite number'
            raise DataError(msg, file=file, column=name, row=int(numbers[i]))
    raise AssertionError('unreachable: a bad cell must have been found')  # pragma: no cover
