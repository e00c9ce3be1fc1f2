"""A small, strict subset of YAML read without PyYAML, so that ``simulate`` starts faster.

Importing PyYAML costs about 15-20 ms at every process start (its reader compiles a large
Unicode character class) and its pure-Python loader about 5 ms more for a machine config:
a tenth of the start-up budget of issue 10. Machine configs are plain block mappings of
numbers and names, so :func:`parse_subset` reads exactly that subset and gives up
(returns ``None``) on anything else; :mod:`.safeyaml` then parses the text with PyYAML as
before. A text either parses here to the same data PyYAML gives (values, types, key order)
or is left to PyYAML, which also reports every error: this module never raises for input.

The subset (anything outside it is left to PyYAML):

* ASCII structure; non-ASCII characters only inside comments (and only those PyYAML
  accepts); no tabs, carriage returns, byte-order marks, directives or document markers;
* a block mapping at the top; block mappings nested by indentation, keys and values on
  one line (``key: value`` or ``key:`` followed by a deeper block or nothing, which is
  null); block sequences of single-line items (``- value``) under a key, indented deeper;
* values: flow collections closed on their line (``{a: 1, b: [1, 2]}``), and plain
  scalars of these forms only, resolved as PyYAML's YAML 1.1 resolver does:
  decimal integers without leading zeros or underscores, decimals with a dot
  (``1.0``, ``-5.0e-5``: an exponent needs its sign, as in PyYAML), ``null``/``~``,
  PyYAML's boolean words (``true``, ``yes``, ``off``, ...) and names starting with a
  letter or ``_`` made of letters, digits and ``_ . - / ( ) +``;
* comments: ``#`` at the start of a line or after a blank;
* no quotes, anchors, aliases, tags, block scalars (``|``, ``>``), complex keys,
  multi-line plain scalars, duplicate keys, or nesting deeper than ``max_depth``.
"""
from __future__ import annotations

import re
from typing import Any

__all__ = ['parse_subset']

_BOOL = {'yes': True, 'Yes': True, 'YES': True, 'no': False, 'No': False, 'NO': False,
         'true': True, 'True': True, 'TRUE': True, 'false': False, 'False': False,
         'FALSE': False, 'on': True, 'On': True, 'ON': True, 'off': False, 'Off': False,
         'OFF': False}
_NULL = ('null', 'Null', 'NULL', '~')
_INT = re.compile(r'[-+]?(?:0|[1-9][0-9]{0,17})')
_FLOAT = re.compile(r'[-+]?[0-9]{1,30}\.[0-9]{0,30}(?:[eE][-+][0-9]{1,3})?')
_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_./()+\-]*')
_KEY_LINE = re.compile(r'( *)([^ :#][^:#]*?):(?: +(.*))?')
_FLOW_TOKEN = re.compile(r' *([\[\]{},]|[^\[\]{},: ][^\[\]{},:]*?(?= *[\[\]{},:]|$)|: )')


class _Unsupported(Exception):
    """Outside the subset: the caller falls back to PyYAML."""


def parse_subset(text: str, *, max_depth: int) -> dict | None:
    """Parse ``text`` if it lies in this module's YAML subset.

    Parameters
    ----------
    text
        A whole document.
    max_depth
        Deepest nesting accepted here (deeper texts go to PyYAML, which refuses them).

    Returns
    -------
    dict or None
        The top-level mapping, equal to what PyYAML's safe loader builds from ``text``;
        ``None`` when the text is outside the subset (including every invalid text).
    """
    try:
        return _Parser(text, max_depth).document()
    except (_Unsupported, RecursionError):
        return None


def _scalar(word: str) -> Any:
    """A plain scalar's value by PyYAML's implicit resolvers, for the forms of the subset."""
    if _FLOAT.fullmatch(word):
        return float(word)
    if _INT.fullmatch(word):
        return int(word)
    if word in _NULL:
        return None
    value = _BOOL.get(word)
    if value is not None:
        return value
    if _NAME.fullmatch(word):
        return word
    raise _Unsupported(word)


def _strip_comment(line: str) -> str:
    """The line without its comment (``#`` at the start or after a blank) and end blanks."""
    cut = line.find('#')
    while cut > 0 and line[cut - 1] != ' ':
        cut = line.find('#', cut + 1)
    if cut >= 0:
        line = line[:cut]
    return line.rstrip(' ')


def _printable(ch: str) -> bool:
    """Whether PyYAML's reader accepts the (non-ASCII) character."""
    o = ord(ch)
    return (o == 0x85 or 0xA0 <= o <= 0xD7FF or 0xE000 <= o <= 0xFFFD
            or 0x10000 <= o <= 0x10FFFF) and o != 0xFEFF


class _Parser:
    """Block structure by indentation; flow collections by a small recursive descent."""

    def __init__(self, text: str, max_depth: int) -> None:
        if not text.isascii() and any(c in text for c in '\x85\u2028\u2029\ufeff'):
            raise _Unsupported('a line break other than newline, or a byte-order mark')
        lines = []
        for raw in text.split('\n'):
            if not raw.isascii():
                if not all(_printable(ch) for ch in set(raw) if not ch.isascii()) \
                        or not ''.join(ch for ch in raw if ch.isascii()).isprintable():
                    raise _Unsupported('control character or one PyYAML refuses')
            elif not raw.isprintable():
                # tabs, carriage returns and other control characters
                raise _Unsupported('control character')
            line = _strip_comment(raw)
            if line:
                if not line.isascii():
                    raise _Unsupported('non-ASCII outside a comment')
                if line.startswith(('---', '...', '%')):
                    raise _Unsupported('document marker or directive')
                if any(c in line for c in '\'"&*!|>%@`?'):
                    raise _Unsupported('quote, anchor, alias, tag or block scalar')
                lines.append(line)
        self.lines = lines
        self.i = 0
        self.max_depth = max_depth

    def document(self) -> dict:
        if not self.lines:
            raise _Unsupported('empty document')
        out = self.mapping(0, 1)
        if self.i != len(self.lines):
            raise _Unsupported('text after the top-level mapping')
        return out

    def indent(self) -> int | None:
        if self.i >= len(self.lines):
            return None
        line = self.lines[self.i]
        return len(line) - len(line.lstrip(' '))

    def mapping(self, indent: int, depth: int) -> dict:
        if depth > self.max_depth:
            raise _Unsupported('too deep')
        out: dict = {}
        while self.indent() == indent:
            m = _KEY_LINE.fullmatch(self.lines[self.i])
            if m is None or m.group(2).startswith('- ') or m.group(2) == '-':
                raise _Unsupported('not a "key: value" line')
            key = _scalar(m.group(2).rstrip(' '))
            if isinstance(key, bool) or key is None or key in out:
                raise _Unsupported('null, boolean or repeated key')
            value = m.group(3)
            self.i += 1
            deeper = self.indent()
            if value:
                if deeper is not None and deeper > indent:
                    raise _Unsupported('continuation line')
                out[key] = self.value(value, depth + 1)
            elif deeper is None or deeper <= indent:
                out[key] = None
            elif self.lines[self.i].lstrip(' ').startswith('-'):
                out[key] = self.sequence(deeper, depth + 1)
            else:
                out[key] = self.mapping(deeper, depth + 1)
        level = self.indent()
        if level is not None and level > indent:
            raise _Unsupported('indentation does not match a level above')
        return out

    def sequence(self, indent: int, depth: int) -> list:
        if depth > self.max_depth:
            raise _Unsupported('too deep')
        out = []
        while self.indent() == indent:
            item = self.lines[self.i][indent:]
            if not item.startswith('- '):
                raise _Unsupported('not a "- value" line')
            self.i += 1
            deeper = self.indent()
            if deeper is not None and deeper > indent:
                raise _Unsupported('nested block in a sequence')
            out.append(self.value(item[2:].lstrip(' '), depth + 1))
        return out

    def value(self, text: str, depth: int) -> Any:
        if text[0] in '[{':
            tokens = _FLOW_TOKEN.findall(text)
            if ''.join(tokens).replace(' ', '') != text.replace(' ', ''):
                raise _Unsupported('flow collection')
            tokens = [t.strip(' ') if t != ': ' else t for t in tokens]
            value, end = self.flow(tokens, 0, depth)
            if end != len(tokens):
                raise _Unsupported('text after a flow collection')
            return value
        if text[0] in '-:,]}' and not _FLOAT.fullmatch(text) and not _INT.fullmatch(text):
            raise _Unsupported('indicator')
        if ': ' in text or text.endswith(':') or ' #' in text or ',' in text:
            raise _Unsupported('mapping or flow indicator in a plain scalar')
        return _scalar(text)

    def flow(self, tokens: list[str], at: int, depth: int) -> tuple[Any, int]:
        """The flow node starting at ``tokens[at]`` and the index after it."""
        if depth > self.max_depth:
            raise _Unsupported('too deep')
        if at >= len(tokens):
            raise _Unsupported('unclosed flow collection')
        tok = tokens[at]
        if tok == '[':
            out: list = []
            at += 1
            while True:
                if at < len(tokens) and tokens[at] == ']' and not out:
                    return out, at + 1
                item, at = self.flow(tokens, at, depth + 1)
                out.append(item)
                at = self.separator(tokens, at, ']')
                if at < 0:
                    return out, -at
        if tok == '{':
            mapping: dict = {}
            at += 1
            while True:
                if at < len(tokens) and tokens[at] == '}' and not mapping:
                    return mapping, at + 1
                key = tokens[at] if at < len(tokens) else ''
                if key in '[]{},' or key == ': ' or at + 1 >= len(tokens) \
                        or tokens[at + 1] != ': ':
                    raise _Unsupported('flow mapping entry')
                key = _scalar(key)
                if isinstance(key, bool) or key is None or key in mapping:
                    raise _Unsupported('null, boolean or repeated key')
                mapping[key], at = self.flow(tokens, at + 2, depth + 1)
                at = self.separator(tokens, at, '}')
                if at < 0:
                    return mapping, -at
        if tok in '[]{},' or tok == ': ' or tok[0] in '-' and not (
                _FLOAT.fullmatch(tok) or _INT.fullmatch(tok)):
            raise _Unsupported('flow scalar')
        return _scalar(tok), at + 1

    @staticmethod
    def separator(tokens: list[str], at: int, close: str) -> int:
        """After an item: the next item's index, or minus the index after ``close``."""
        if at < len(tokens) and tokens[at] == close:
            return -(at + 1)
        if at + 1 < len(tokens) and tokens[at] == ',' and tokens[at + 1] not in ',]}':
            return at + 1
        raise _Unsupported('flow separator')
