"""Shipped YAML documents answered without PyYAML: exact snapshots of what it built from them.

Every ``simulate`` reads a machine config; PyYAML's import and its pure-Python parse of a
3 kB config cost about a tenth of a short run's start-up. :data:`.yaml_snapshots.SNAPSHOTS`
maps the exact text of each shipped config (``config/*.yaml``) to a function that builds
the data :func:`.yamlparse.parse_yaml` made from that text, written out as a Python literal
(compiled and cached like any module; each call builds a fresh copy). :func:`known_document`
answers a text only if it is one of those texts, character for character; any other text
(an edited config, a user's file) goes to PyYAML as before, with every limit of
:mod:`.safeyaml`.

A document is snapshotted only if a literal carries its data exactly
(:func:`snapshot_literal`): mappings, lists, text, integers, finite floats, booleans and
null (no dates, sets or binary), no value shared through an alias, and the literal read back
(:func:`ast.literal_eval`) equal to the data in value, type and key order.
``scripts/yaml_snapshots.py`` writes the table (``render_table`` there); a test fails when
a shipped config and its snapshot differ (regenerate with that script).
"""
from __future__ import annotations

import math
from typing import Any

__all__ = ['known_document', 'NOT_KNOWN', 'snapshot_literal', 'same_data']

NOT_KNOWN = object()
"""Returned by :func:`known_document` for a text without a snapshot."""

_WIDTH = 85         # of a literal's lines, indented by 8 in the generated module


def known_document(text: str) -> Any:
    """The data of a snapshotted document (a fresh copy), else :data:`NOT_KNOWN`."""
    from .yaml_snapshots import SNAPSHOTS
    build = SNAPSHOTS.get(text)
    return NOT_KNOWN if build is None else build()


def snapshot_literal(data: Any) -> str | None:
    """``data`` as a Python literal if the literal carries it exactly (see the module
    docstring), else ``None``."""
    import ast
    import pprint
    if not _plain(data, set()):
        return None
    text = pprint.pformat(data, width=_WIDTH, sort_dicts=False)
    return text if same_data(ast.literal_eval(text), data) else None


def _plain(x: Any, seen: set[int]) -> bool:
    t = type(x)
    if t is str or t is int or t is bool or x is None:
        return True
    if t is float:
        return math.isfinite(x)
    if t is not dict and t is not list:
        return False
    if id(x) in seen:           # the same container twice: an alias
        return False
    seen.add(id(x))
    if t is dict:
        return all(_plain_key(k) and _plain(v, seen) for k, v in x.items())
    return all(_plain(v, seen) for v in x)


def _plain_key(k: Any) -> bool:
    t = type(k)
    return (t is str or t is int or t is bool or k is None
            or (t is float and math.isfinite(k)))


def same_data(a: Any, b: Any) -> bool:
    """Equal in value, type (``1`` is not ``1.0`` nor ``True``) and key order, recursively."""
    if type(a) is not type(b):
        return False
    if type(a) is dict:
        ka, kb = list(a), list(b)
        return (len(ka) == len(kb) and all(same_data(x, y) for x, y in zip(ka, kb))
                and all(same_data(a[k], b[k]) for k in ka))
    if type(a) is list:
        return len(a) == len(b) and all(same_data(x, y) for x, y in zip(a, b))
    if type(a) is float:
        return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)
    return a == b
