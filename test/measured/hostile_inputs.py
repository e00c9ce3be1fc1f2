"""Builders of small valid inputs, their damaged variants, and the outcome check of the CLI.

Shared by the regression and property tests of the input boundary
(``test_hostile_inputs.py``, ``test_hostile_properties.py``) and by the node test of
``measured_replay`` (loaded there by path). Nothing here knows an expected number: the
check is only "exit 0 with finite output, or exit 1 with clear error lines".
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import os
from pathlib import Path
import re
import shutil
from typing import Callable

import numpy as np
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
import yaml

from feed_axis_energy.cli import main
from feed_axis_energy.record import bagio
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.importer import import_campaign

ROOT = Path(__file__).resolve().parents[2]
MACHINE = ROOT / 'config' / 'demonstrator.yaml'
SHORT_PROGRAM = 'G21 G90 G94\nG0 X0\nG1 X20 F3000\nG1 X0 F6000\n'


# ----------------------------------------------------------------------------- valid inputs

def csv_text(*, n: int = 40, phase: float = 0.0) -> str:
    """A measured run of the X axis: time [s], power [kW], position [mm]."""
    lines = ['t,P,X']
    for i in range(n):
        x = 40.0 * math.sin(i / 6.0 + phase)
        p = 0.05 + 0.02 * abs(math.cos(i / 6.0 + phase))
        lines.append(f'{i * 0.1:.3f},{p:.5f},{x:.4f}')
    return '\n'.join(lines) + '\n'


def manifest_text(runs: list[str], *, machine: Path = MACHINE, unit: str = 'kW') -> str:
    """A manifest of CSV runs ``<name>.csv`` next to it, in plain YAML."""
    lines = [f'machine: {json.dumps(str(machine))}',
             'defaults:',
             '  load_kg: 0.0',
             '  motion: {from_data: actual}',
             '  time: {column: t, unit: s}',
             '  axes:',
             f'    X: {{power: {{column: P, unit: {unit}}}, position: {{column: X, unit: mm}}}}',
             'runs:']
    lines += [f'  - {{name: {name}, data: {name}.csv}}' for name in runs]
    return '\n'.join(lines) + '\n'


def csv_campaign(root: Path, *, runs: int = 1, n: int = 40, cell: str | None = None,
                 unit: str = 'kW') -> Path:
    """Write ``runs`` CSV runs and their manifest into ``root``; ``cell`` replaces the power
    of data row 10 of the first run. Returns the manifest."""
    root.mkdir(parents=True, exist_ok=True)
    names = [f'r{k}' for k in range(runs)]
    for k, name in enumerate(names):
        text = csv_text(n=n, phase=float(k))
        if cell is not None and k == 0:
            lines = text.splitlines()
            fields = lines[10].split(',')
            fields[1] = cell
            lines[10] = ','.join(fields)
            text = '\n'.join(lines) + '\n'
        (root / f'{name}.csv').write_text(text)
    manifest = root / 'm.yaml'
    manifest.write_text(manifest_text(names, unit=unit))
    return manifest


def bag_campaign(root: Path, *, runs: int = 1, n: int = 40, batch: int = 10) -> Path:
    """Import a CSV campaign into measured-run bags under ``root/bags``; return its manifest.

    The bags are named ``r0``, ``r1``, ...; ``batch`` samples per message, so a bag holds
    several messages per topic.
    """
    src = csv_campaign(root / 'csv', runs=runs, n=n)
    result = import_campaign(load_campaign(src), root / 'bags', batch=batch)
    return result.manifest


def mcap_file(bag: Path) -> Path:
    """The (single) storage file of a bag directory."""
    return next(p for p in sorted(bag.iterdir()) if p.name != 'metadata.yaml')


# ----------------------------------------------------------------------------- damage

def _set_custom(bag: Path, value: str) -> None:
    meta = bag / 'metadata.yaml'
    doc = yaml.safe_load(meta.read_text())
    doc['rosbag2_bagfile_information']['custom_data']['feed_axis_energy/measured_run'] = value
    meta.write_text(yaml.safe_dump(doc))


def _truncate(fraction: float) -> Callable[[Path], None]:
    def damage(bag: Path) -> None:
        f = mcap_file(bag)
        data = f.read_bytes()
        f.write_bytes(data[:int(len(data) * fraction)])
    return damage


def _flip(seed: int, count: int) -> Callable[[Path], None]:
    def damage(bag: Path) -> None:
        f = mcap_file(bag)
        data = bytearray(f.read_bytes())
        rng = np.random.default_rng(seed)
        for i in rng.integers(0, len(data), size=count):
            data[i] ^= 0xFF
        f.write_bytes(bytes(data))
    return damage


def _random_mcap(bag: Path) -> None:
    mcap_file(bag).write_bytes(np.random.default_rng(7).bytes(4000))


def _zero_length(bag: Path) -> None:
    mcap_file(bag).write_bytes(b'')


def _symlink_loop(bag: Path) -> None:
    f = mcap_file(bag)
    f.unlink()
    os.symlink(f.name, f)


def _metadata_loop(bag: Path) -> None:
    (bag / 'metadata.yaml').unlink()
    os.symlink('metadata.yaml', bag / 'metadata.yaml')


def _sqlite3_storage(bag: Path) -> None:
    meta = bag / 'metadata.yaml'
    f = mcap_file(bag)
    meta.write_text(meta.read_text().replace('storage_identifier: mcap',
                                             'storage_identifier: sqlite3')
                    .replace(f.name, f.stem + '.db3'))
    f.rename(f.with_suffix('.db3'))


def _rewrite(bag: Path, make: Callable[[str, int, object], list]) -> None:
    """Rewrite a bag's messages through ``make(topic, stamp_ns, message)``, which returns
    ``[(topic, msgtype, stamp_ns, message)]``; custom_data is kept."""
    ts = bagio.typestore()
    info = bagio.read_metadata(bag)
    with Reader(bag) as reader:
        items = [(c.topic, t, ts.deserialize_cdr(raw, c.msgtype))
                 for c, t, raw in reader.messages()]
    tmp = bag.with_name(bag.name + '.new')
    writer = Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conns: dict[str, object] = {}
    for topic, stamp, msg in items:
        for out_topic, msgtype, out_stamp, out_msg in make(topic, stamp, msg):
            if out_topic not in conns:
                conns[out_topic] = writer.add_connection(out_topic, msgtype, typestore=ts)
            if out_msg is not None:
                writer.write(conns[out_topic], out_stamp, ts.serialize_cdr(out_msg, msgtype))
    for key, value in (info.get('custom_data') or {}).items():
        writer.set_custom_data(key, value)
    writer.close()
    shutil.rmtree(bag)
    tmp.rename(bag)


def to_sqlite3(bag: Path) -> None:
    """Rewrite a bag with the same messages and custom_data in sqlite3 storage (valid)."""
    info = bagio.read_metadata(bag)
    with Reader(bag) as reader:
        items = [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages()]
    tmp = bag.with_name(bag.name + '.new')
    writer = Writer(tmp, version=9, storage_plugin=StoragePlugin.SQLITE3)
    writer.open()
    conns: dict[str, object] = {}
    for topic, msgtype, stamp, raw in items:
        if topic not in conns:
            conns[topic] = writer.add_connection(topic, msgtype, typestore=bagio.typestore())
        writer.write(conns[topic], stamp, raw)
    for key, value in (info.get('custom_data') or {}).items():
        writer.set_custom_data(key, value)
    writer.close()
    shutil.rmtree(bag)
    tmp.rename(bag)


def _sqlite3_truncated(bag: Path) -> None:
    to_sqlite3(bag)
    db = next(bag.glob('*.db3'))
    data = db.read_bytes()
    db.write_bytes(data[:len(data) // 2])


def _wrong_type(bag: Path) -> None:
    string = bagio.typestore().types['std_msgs/msg/String']

    def make(topic, stamp, msg):
        if topic == bagio.TOPIC_MEASURED_POWER:
            return [(topic, 'std_msgs/msg/String', stamp, string(data='not a trajectory'))]
        return [(topic, bagio.JOINT_TRAJECTORY, stamp, msg)]
    _rewrite(bag, make)


def _no_messages(bag: Path) -> None:
    _rewrite(bag, lambda topic, stamp, msg: [(topic, bagio.JOINT_TRAJECTORY, stamp, None)])


def _edit_points(edit: Callable[[object], None]) -> Callable[[Path], None]:
    def damage(bag: Path) -> None:
        done = []

        def make(topic, stamp, msg):
            if topic == bagio.TOPIC_MEASURED_POWER and not done:
                edit(msg)
                done.append(1)
            return [(topic, bagio.JOINT_TRAJECTORY, stamp, msg)]
        _rewrite(bag, make)
    return damage


def _short_array(msg) -> None:
    msg.points[1].velocities = msg.points[1].velocities[:-1].copy()


def _nan_value(msg) -> None:
    msg.points[2].velocities = np.full_like(msg.points[2].velocities, np.nan)


def _huge_value(msg) -> None:
    msg.points[2].velocities = np.full_like(msg.points[2].velocities, 1e300)


BAG_DAMAGES: dict[str, Callable[[Path], None]] = {
    'zero-length mcap': _zero_length,
    'truncated mcap 10 %': _truncate(0.1),
    'truncated mcap 50 %': _truncate(0.5),
    'truncated mcap 99 %': _truncate(0.99),
    'random mcap': _random_mcap,
    'flipped bytes a': _flip(1, 3),
    'flipped bytes b': _flip(2, 20),
    'flipped bytes c': _flip(3, 200),
    'wrong message type': _wrong_type,
    'custom_data not JSON': lambda bag: _set_custom(bag, '{not json'),
    'custom_data nested 100000 deep': lambda bag: _set_custom(bag, '[' * 100000),
    'custom_data rows absurd': lambda bag: _set_custom(bag, '{"rows": [[1, 1000000000000000]]}'),
    'empty metadata.yaml': lambda bag: (bag / 'metadata.yaml').write_text(''),
    'broken metadata.yaml': lambda bag: (bag / 'metadata.yaml').write_text('{[: x\n'),
    'metadata.yaml not UTF-8': lambda bag: (bag / 'metadata.yaml').write_bytes(b'\xff\xfe'),
    'sqlite3 storage (an MCAP file)': _sqlite3_storage,
    'sqlite3 storage, truncated': _sqlite3_truncated,
    'symlink loop (storage file)': _symlink_loop,
    'symlink loop (metadata.yaml)': _metadata_loop,
    'topics without messages': _no_messages,
    'array shorter than joint names': _edit_points(_short_array),
    'NaN in a message': _edit_points(_nan_value),
    'value 1e300 in a message': _edit_points(_huge_value),
}
"""Damages of a measured-run bag directory, applied in place; each is a case of issue 9."""


# ----------------------------------------------------------------------------- outcome

_NONFINITE = re.compile(r'(?<![\w.])-?(nan|inf|infinity)(?![\w.])', re.IGNORECASE)


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """Run the command line in-process; return exit code, stdout and stderr.

    Any exception other than ``SystemExit`` propagates: that is the failure we look for.
    """
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse usage errors
            code = exc.code if isinstance(exc.code, int) else 2
    return code, out.getvalue(), err.getvalue()


def check_outcome(code: int, out: str, err: str, *, json_output: bool = False) -> None:
    """Assert: exit 0 with finite output, or exit 1 with clear ``error:`` lines only.

    A clear line names a place (``file: ...``), is at most a few hundred characters long, and
    no traceback or Python exception name appears.
    """
    assert 'Traceback' not in err + out, err[-2000:]
    if code == 0:
        assert not _NONFINITE.search(out), f'non-finite number in the output:\n{out[-2000:]}'
        if json_output:
            def refuse(name: str) -> None:
                raise AssertionError(f'{name} in the JSON output')
            json.loads(out, parse_constant=refuse)
        return
    assert code == 1, f'exit {code}: {err[-2000:]}'
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines, 'exit 1 without a message'
    errors = [ln for ln in lines if ln.startswith('error: ')]
    assert errors, f'no "error: " line in {err[-2000:]!r}'
    for line in errors:
        assert len(line) < 600, f'an unbounded message ({len(line)} characters)'
        assert not re.search(r'\b\w+(Error|Exception)\b: ', line.replace('error: ', '', 1)), \
            line
