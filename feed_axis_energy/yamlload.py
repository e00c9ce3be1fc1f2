"""PyYAML's safe loader with the limits of :mod:`.safeyaml` (nesting depth, alias expansion).

Imported by :func:`.safeyaml.load_yaml_text` only for a text outside the subset that
:mod:`.yamlsubset` reads (importing PyYAML costs start-up time); the rules are those of
:mod:`.safeyaml`'s docstring.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, SequenceNode

from .errors import shorten

__all__ = ['load_pyyaml']


class _LimitExceeded(Exception):
    """Raised inside the loader; turned into the caller's error type with the place."""

    def __init__(self, message: str, mark: Any = None):
        super().__init__(message)
        self.mark = mark


class _BoundedLoader(yaml.SafeLoader):
    """PyYAML's safe loader with a nesting limit and alias bookkeeping."""

    def __init__(self, stream: str, max_depth: int):
        super().__init__(stream)
        self._depth = 0
        self._max_depth = max_depth
        self.aliases = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node:
        if self.check_event(yaml.AliasEvent):
            self.aliases += 1
            return super().compose_node(parent, index)
        self._depth += 1
        try:
            if self._depth > self._max_depth:
                msg = f'nested deeper than {self._max_depth} levels'
                raise _LimitExceeded(msg, self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def _expanded_size(root: Node, budget: int) -> int:
    """Count the values of ``root`` with aliases expanded; stop once above ``budget``."""
    sizes: dict[int, int] = {}
    on_path: set[int] = set()
    # iterative post-order walk: (node, children done?)
    stack: list[tuple[Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            on_path.discard(key)
            total = 1 + sum(sizes[id(c)] for c in _children(node))
            sizes[key] = total
            if total > budget:
                return total
            continue
        if key in sizes:
            continue
        if key in on_path:
            raise _LimitExceeded('an alias refers to the node that contains it (recursive '
                                 'alias)', node.start_mark)
        on_path.add(key)
        stack.append((node, True))
        for child in _children(node):
            if id(child) in on_path:
                raise _LimitExceeded('an alias refers to the node that contains it '
                                     '(recursive alias)', child.start_mark)
            if id(child) not in sizes:
                stack.append((child, False))
    return sizes[id(root)]


def _children(node: Node) -> list[Node]:
    if isinstance(node, SequenceNode):
        return list(node.value)
    if isinstance(node, MappingNode):
        return [n for pair in node.value for n in pair]
    return []


def _where(mark: Any) -> str:
    if mark is None:
        return ''
    return f'line {mark.line + 1}, column {mark.column + 1}: '


def _yaml_message(err: yaml.YAMLError) -> str:
    mark = getattr(err, 'problem_mark', None)
    problem = getattr(err, 'problem', None)
    if problem is None:
        # the first line only: PyYAML appends a quoted excerpt of the input
        problem = str(err).splitlines()[0] if str(err) else type(err).__name__
    context = getattr(err, 'context', None)
    text = f'{context}: {problem}' if context else str(problem)
    return f'{_where(mark)}not valid YAML: {shorten(text, limit=120)}'


def load_pyyaml(text: str, *, file: str, make_error: Callable[[str, str], Exception],
                max_depth: int, max_expanded: int) -> Any:
    """Parse one YAML document with PyYAML's safe loader and the two limits.

    Parameters
    ----------
    text
        The document.
    file
        Names the source in errors.
    make_error
        Builds the caller's error from a message and the file name.
    max_depth
        Deepest nesting accepted.
    max_expanded
        Most values the document may hold once every alias is expanded.

    Returns
    -------
    Any
        Plain Python data (``None`` for an empty document).

    Raises
    ------
    Exception
        What ``make_error`` builds: syntax error, nesting or alias expansion above the
        limits, a recursive alias or a value PyYAML cannot build, naming line and column
        where known.
    """
    try:
        loader = _BoundedLoader(text, max_depth)
    except yaml.reader.ReaderError as err:
        pos = int(err.position)
        line = text.count('\n', 0, pos) + 1
        column = pos - (text.rfind('\n', 0, pos) + 1) + 1
        msg = (f'line {line}, column {column}: character U+{int(err.character):04X} is not '
               'allowed in YAML (control character); expected printable text')
        raise make_error(msg, file) from None
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if loader.aliases:
            size = _expanded_size(node, max_expanded)
            if size > max_expanded:
                msg = (f'{loader.aliases} aliases (*name) expand the document to more than '
                       f'{max_expanded} values; expected plain data (write the values '
                       'out, or use fewer nested aliases)')
                raise _LimitExceeded(msg)
        return loader.construct_document(node)
    except _LimitExceeded as err:
        raise make_error(f'{_where(err.mark)}{err}', file) from None
    except yaml.YAMLError as err:
        raise make_error(_yaml_message(err), file) from None
    except (ValueError, OverflowError, TypeError) as err:
        # PyYAML's constructors let these through, e.g. a timestamp 2024-13-45 or an
        # integer of more than 4300 digits
        msg = f'not valid YAML: a value cannot be read ({shorten(str(err), limit=120)})'
        raise make_error(msg, file) from None
    finally:
        loader.dispose()
