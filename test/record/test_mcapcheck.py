"""MCAP framing check: damaged length fields are refused before rosbags allocates them."""
from pathlib import Path
import struct

import numpy as np
import pytest

from feed_axis_energy.record import bagio, StreamBagWriter
from feed_axis_energy.errors import DataError
from feed_axis_energy.record.mcapcheck import check_mcap, MAX_CHUNK_BYTES

MAGIC = b'\x89MCAP0\r\n'


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    t = np.arange(50) * 0.01
    series = bagio.Series(t=t, names=('X', 'total'), velocities=np.ones((50, 2)))
    with StreamBagWriter(tmp_path / 'bag') as writer:
        writer.write_series('/power', series, batch=10)
    return tmp_path / 'bag'


def records(data: bytes) -> list[tuple[int, int, int]]:
    """``(offset, opcode, length)`` of every top-level record, by the MCAP layout."""
    out, pos = [], len(MAGIC)
    while pos < len(data) - len(MAGIC):
        opcode, length = data[pos], struct.unpack_from('<Q', data, pos + 1)[0]
        out.append((pos, opcode, length))
        if opcode == 0x02:
            break
        pos += 9 + length
    return out


def storage(bag: Path) -> Path:
    return next(bag.glob('*.mcap'))


def test_valid_file_passes_and_reads(bag: Path) -> None:
    check_mcap(storage(bag))
    assert bagio.read_series(bag, '/power').t.shape == (50,)
    assert any(op == 0x06 for _, op, _ in records(storage(bag).read_bytes()))


def test_record_length_beyond_the_file(bag: Path) -> None:
    f = storage(bag)
    data = bytearray(f.read_bytes())
    offset, opcode, _ = next(r for r in records(bytes(data)) if r[1] == 0x06)
    data[offset + 1:offset + 9] = struct.pack('<Q', 2**32)   # one damaged length: 4 GiB
    f.write_bytes(bytes(data))
    with pytest.raises(DataError, match=f'byte {offset}: a record .* claims 4294967296 bytes'):
        check_mcap(f, bag=bag)
    with pytest.raises(DataError, match='claims 4294967296 bytes') as info:
        bagio.read_series(bag, '/power')          # refused before rosbags allocates
    assert str(info.value).startswith(str(bag))


def test_summary_offset_not_at_a_record(bag: Path) -> None:
    f = storage(bag)
    data = bytearray(f.read_bytes())
    footer = next(r for r in records(bytes(data)) if r[1] == 0x02)[0]
    summary = struct.unpack_from('<Q', data, footer + 9)[0]
    data[footer + 9:footer + 17] = struct.pack('<Q', summary + 3)
    f.write_bytes(bytes(data))
    with pytest.raises(DataError, match='summary start .* is not the start of a record'):
        bagio.bag_topics(bag)


def test_chunk_index_pointing_elsewhere_and_huge_chunks(bag: Path) -> None:
    f = storage(bag)
    good = f.read_bytes()
    index = next(r for r in records(good) if r[1] == 0x08)[0]
    data = bytearray(good)
    start = struct.unpack_from('<Q', data, index + 9 + 16)[0]
    data[index + 9 + 16:index + 9 + 24] = struct.pack('<Q', start + 1)
    f.write_bytes(bytes(data))
    with pytest.raises(DataError, match='where no chunk starts'):
        check_mcap(f)
    chunk = next(r for r in records(good) if r[1] == 0x06)[0]
    data = bytearray(good)
    data[chunk + 9 + 16:chunk + 9 + 24] = struct.pack('<Q', MAX_CHUNK_BYTES + 1)
    f.write_bytes(bytes(data))
    with pytest.raises(DataError, match='uncompressed, more than'):
        check_mcap(f)


def test_cut_files_are_refused_at_the_cut(bag: Path) -> None:
    f = storage(bag)
    good = f.read_bytes()
    for cut in (len(good) // 3, len(good) - 40):
        f.write_bytes(good[:cut] + good[-len(MAGIC):])   # cut, but ending in the magic
        with pytest.raises(DataError, match='the file is truncated or damaged'):
            check_mcap(f)
