"""Sparkplug B payloads: the protobuf wire form of ``Payload`` and ``Payload.Metric``.

A small encoder and decoder of the messages of Eclipse Tahu's ``sparkplug_b.proto``
(Sparkplug 3.0) that the bridge uses: ``Payload`` (``timestamp`` 1, ``metrics`` 2, ``seq``
3), ``Metric`` (``name`` 1, ``alias`` 2, ``timestamp`` 3, ``datatype`` 4, ``is_null`` 7,
``properties`` 9, the scalar values 10-16) and ``PropertySet``/``PropertyValue`` (scalar
values only). Fields the bridge does not use (data sets, templates, metadata, extensions)
are skipped when decoding, as protobuf readers do with unknown fields.

Wire form (protobuf 2): a field is a key ``(number << 3) | wire_type`` as a varint, then a
varint (wire type 0), 8 little-endian bytes (1), a varint length and that many bytes (2)
or 4 little-endian bytes (5). Signed Sparkplug integers travel as their two's complement in
the unsigned field (``int_value`` uint32 for 8/16/32 bits, ``long_value`` uint64 for 64).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import struct
from typing import Any, Mapping

from ..errors import describe, RequestError

__all__ = ['decode_sparkplug', 'encode_sparkplug', 'MAX_DECODED_BYTES', 'SpDataType', 'SpMetric',
           'SpPayload']

MAX_DECODED_BYTES = 256 * 1024
"""Largest payload :func:`decode_sparkplug` reads (commands to the bridge are small)."""


class SpDataType:
    """Sparkplug B data types (``Payload.Metric.datatype``), the subset used here."""

    INT8 = 1
    INT16 = 2
    INT32 = 3
    INT64 = 4
    UINT8 = 5
    UINT16 = 6
    UINT32 = 7
    UINT64 = 8
    FLOAT = 9
    DOUBLE = 10
    BOOLEAN = 11
    STRING = 12
    DATETIME = 13
    TEXT = 14


_SIGNED_BITS = {SpDataType.INT8: 8, SpDataType.INT16: 16, SpDataType.INT32: 32,
                SpDataType.INT64: 64}
_INT_FIELD = (SpDataType.INT8, SpDataType.INT16, SpDataType.INT32, SpDataType.UINT8,
              SpDataType.UINT16, SpDataType.UINT32)
_LONG_FIELD = (SpDataType.INT64, SpDataType.UINT64, SpDataType.DATETIME)
_TEXT = (SpDataType.STRING, SpDataType.TEXT)
_U64 = (1 << 64) - 1


@dataclass(frozen=True)
class SpMetric:
    """One Sparkplug metric.

    Attributes
    ----------
    name
        Metric name (births, commands); None in data messages that use the alias.
    alias
        Numeric alias tied to the name in the birth; None when not used.
    datatype
        One of :class:`SpDataType`.
    value
        ``int``, ``float``, ``bool`` or ``str`` after the datatype; None when ``is_null``.
    timestamp_ms
        When the value was taken [ms since the UNIX epoch], or None.
    is_null
        The value is explicitly null.
    properties
        Property name -> ``(datatype, value)`` (for example ``engUnit`` -> ``(12, 'W')``).
    """

    name: str | None
    alias: int | None
    datatype: int
    value: Any
    timestamp_ms: int | None = None
    is_null: bool = False
    properties: Mapping[str, tuple[int, Any]] = field(default_factory=dict)


@dataclass(frozen=True)
class SpPayload:
    """A Sparkplug payload: send time [ms], metrics, sequence number (None in NDEATH)."""

    timestamp_ms: int | None
    metrics: tuple[SpMetric, ...]
    seq: int | None = None


# --- encoding ----------------------------------------------------------------------------

def _varint(value: int) -> bytes:
    if value < 0 or value > _U64:
        raise ValueError(f'a varint must be 0...2**64-1, got {value}')
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def _key(number: int, wire: int) -> bytes:
    return _varint((number << 3) | wire)


def _len_field(number: int, data: bytes) -> bytes:
    return _key(number, 2) + _varint(len(data)) + data


def _scalar(datatype: int, value: Any, *, int_no: int, long_no: int, float_no: int,
            double_no: int, bool_no: int, string_no: int) -> bytes:
    """One value in the field its datatype selects (field numbers of Metric or PropertyValue)."""
    if datatype in _INT_FIELD or datatype in _LONG_FIELD:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f'datatype {datatype} needs an integer, got {describe(value)}')
        bits = 64 if datatype in _LONG_FIELD else 32
        return _key(long_no if bits == 64 else int_no, 0) + _varint(value & ((1 << bits) - 1))
    if datatype == SpDataType.FLOAT:
        return _key(float_no, 5) + struct.pack('<f', float(value))
    if datatype == SpDataType.DOUBLE:
        return _key(double_no, 1) + struct.pack('<d', float(value))
    if datatype == SpDataType.BOOLEAN:
        return _key(bool_no, 0) + _varint(1 if value else 0)
    if datatype in _TEXT:
        return _len_field(string_no, str(value).encode('utf-8'))
    raise ValueError(f'datatype {datatype} is not supported by this encoder')


def _property_set(properties: Mapping[str, tuple[int, Any]]) -> bytes:
    out = b''.join(_len_field(1, key.encode('utf-8')) for key in properties)
    for datatype, value in properties.values():
        body = _key(1, 0) + _varint(datatype)
        if value is None:
            body += _key(2, 0) + _varint(1)
        else:
            body += _scalar(datatype, value, int_no=3, long_no=4, float_no=5, double_no=6,
                            bool_no=7, string_no=8)
        out += _len_field(2, body)
    return out


def _metric(metric: SpMetric) -> bytes:
    out = b''
    if metric.name is not None:
        out += _len_field(1, metric.name.encode('utf-8'))
    if metric.alias is not None:
        out += _key(2, 0) + _varint(metric.alias)
    if metric.timestamp_ms is not None:
        out += _key(3, 0) + _varint(metric.timestamp_ms)
    out += _key(4, 0) + _varint(metric.datatype)
    null = metric.is_null or metric.value is None or (
        isinstance(metric.value, float) and not math.isfinite(metric.value))
    if null:
        out += _key(7, 0) + _varint(1)
    if metric.properties:
        out += _len_field(9, _property_set(metric.properties))
    if not null:
        out += _scalar(metric.datatype, metric.value, int_no=10, long_no=11, float_no=12,
                       double_no=13, bool_no=14, string_no=15)
    return out


def encode_sparkplug(payload: SpPayload) -> bytes:
    """The protobuf bytes of ``payload`` (fields in number order).

    A float value that is not finite is sent as ``is_null`` (the topic tree's rule: never
    NaN). Raises ``ValueError`` for a value its datatype cannot carry (a program error).
    """
    out = b''
    if payload.timestamp_ms is not None:
        out += _key(1, 0) + _varint(payload.timestamp_ms)
    for metric in payload.metrics:
        out += _len_field(2, _metric(metric))
    if payload.seq is not None:
        out += _key(3, 0) + _varint(payload.seq)
    return out


# --- decoding ----------------------------------------------------------------------------

class _Reader:
    """Fields of one protobuf message: ``(number, wire_type, raw)`` in order."""

    def __init__(self, data: bytes, where: str):
        self.data = data
        self.pos = 0
        self.where = where

    def fail(self, what: str) -> RequestError:
        return RequestError(f'not a Sparkplug B payload: {what} at byte {self.pos}',
                            request=self.where, code='bad_protobuf')

    def varint(self) -> int:
        value, shift = 0, 0
        while True:
            if self.pos >= len(self.data):
                raise self.fail('a varint runs past the end')
            byte = self.data[self.pos]
            self.pos += 1
            value |= (byte & 0x7F) << shift
            if not byte & 0x80:
                return value & _U64
            shift += 7
            if shift > 63:
                raise self.fail('a varint longer than 10 bytes')

    def take(self, n: int) -> bytes:
        if n > len(self.data) - self.pos:
            raise self.fail(f'a field of {n} bytes runs past the end')
        chunk = self.data[self.pos:self.pos + n]
        self.pos += n
        return chunk

    def fields(self) -> list[tuple[int, int, Any]]:
        out = []
        while self.pos < len(self.data):
            key = self.varint()
            number, wire = key >> 3, key & 7
            if number == 0:
                raise self.fail('field number 0')
            if wire == 0:
                raw: Any = self.varint()
            elif wire == 1:
                raw = self.take(8)
            elif wire == 2:
                raw = self.take(self.varint())
            elif wire == 5:
                raw = self.take(4)
            else:
                raise self.fail(f'wire type {wire}')
            out.append((number, wire, raw))
        return out


def _expect(reader: _Reader, wire: int, want: int, name: str) -> None:
    if wire != want:
        raise reader.fail(f'{name} with wire type {wire}, expected {want}')


def _text(reader: _Reader, raw: bytes, name: str) -> str:
    try:
        return raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise reader.fail(f'{name} is not UTF-8') from exc


def _value(reader: _Reader, offset: int, number: int, wire: int, raw: Any) -> Any:
    """A scalar value field; ``offset`` maps Metric's 10... and PropertyValue's 3... to 0..."""
    kind = number - offset
    wires = (0, 0, 5, 1, 0, 2, 2)
    if not 0 <= kind < len(wires):
        return None
    _expect(reader, wire, wires[kind], f'value field {number}')
    if kind in (0, 1):
        return int(raw)
    if kind == 2:
        return struct.unpack('<f', raw)[0]
    if kind == 3:
        return struct.unpack('<d', raw)[0]
    if kind == 4:
        return bool(raw)
    if kind == 5:
        return _text(reader, raw, 'a string value')
    return bytes(raw)


def _typed(datatype: int, value: Any) -> Any:
    """Two's complement back to a signed integer where the datatype is signed."""
    bits = _SIGNED_BITS.get(datatype)
    if bits is not None and isinstance(value, int) and not isinstance(value, bool):
        value &= (1 << bits) - 1
        return value - (1 << bits) if value >> (bits - 1) else value
    return value


def _properties(data: bytes, where: str) -> dict[str, tuple[int, Any]]:
    reader = _Reader(data, where)
    keys: list[str] = []
    values: list[tuple[int, Any]] = []
    for number, wire, raw in reader.fields():
        if number == 1:
            _expect(reader, wire, 2, 'a property key')
            keys.append(_text(reader, raw, 'a property key'))
        elif number == 2:
            _expect(reader, wire, 2, 'a property value')
            inner = _Reader(raw, where)
            datatype, value = 0, None
            for n, w, r in inner.fields():
                if n == 1:
                    _expect(inner, w, 0, 'a property type')
                    datatype = int(r)
                elif 3 <= n <= 8:
                    value = _value(inner, 3, n, w, r)
            values.append((datatype, _typed(datatype, value)))
    if len(keys) != len(values):
        raise reader.fail(f'{len(keys)} property keys for {len(values)} values')
    return dict(zip(keys, values))


def _decode_metric(data: bytes, where: str) -> SpMetric:
    reader = _Reader(data, where)
    name: str | None = None
    alias = timestamp = None
    datatype, value, is_null = 0, None, False
    properties: dict[str, tuple[int, Any]] = {}
    for number, wire, raw in reader.fields():
        if number == 1:
            _expect(reader, wire, 2, 'the metric name')
            name = _text(reader, raw, 'the metric name')
        elif number in (2, 3, 4, 7):
            _expect(reader, wire, 0, f'metric field {number}')
            if number == 2:
                alias = int(raw)
            elif number == 3:
                timestamp = int(raw)
            elif number == 4:
                datatype = int(raw)
            else:
                is_null = bool(raw)
        elif number == 9:
            _expect(reader, wire, 2, 'the metric properties')
            properties = _properties(raw, where)
        elif 10 <= number <= 16:
            value = _value(reader, 10, number, wire, raw)
    if is_null:
        value = None
    return SpMetric(name=name, alias=alias, datatype=datatype, value=_typed(datatype, value),
                    timestamp_ms=timestamp, is_null=is_null, properties=properties)


def decode_sparkplug(data: bytes, *, where: str = 'Sparkplug payload') -> SpPayload:
    """Read a Sparkplug B ``Payload`` message.

    Parameters
    ----------
    data
        The MQTT message's bytes.
    where
        Names the message in errors (its topic).

    Returns
    -------
    SpPayload
        Timestamp, metrics (unknown fields skipped), sequence number.

    Raises
    ------
    RequestError
        Not a well-formed payload (``code`` ``bad_protobuf``) or larger than
        :data:`MAX_DECODED_BYTES` (``too_large``).
    """
    if len(data) > MAX_DECODED_BYTES:
        raise RequestError(f'{len(data)} bytes, more than {MAX_DECODED_BYTES}',
                           request=where, code='too_large')
    reader = _Reader(bytes(data), where)
    timestamp = seq = None
    metrics = []
    for number, wire, raw in reader.fields():
        if number == 1:
            _expect(reader, wire, 0, 'the payload timestamp')
            timestamp = int(raw)
        elif number == 2:
            _expect(reader, wire, 2, 'a metric')
            metrics.append(_decode_metric(raw, where))
        elif number == 3:
            _expect(reader, wire, 0, 'the sequence number')
            seq = int(raw)
    return SpPayload(timestamp_ms=timestamp, metrics=tuple(metrics), seq=seq)
