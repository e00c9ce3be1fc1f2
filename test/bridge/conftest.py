"""Fixtures of the bridge tests: free loopback ports from this suite's ranges, programs.

OPC UA servers take ports from ``FAE_OPCUA_PORTS`` (default 48400-48489), MQTT brokers from
``FAE_MQTT_PORTS`` (default 18830-18889): ranges so that people testing on one machine do not
collide (``bench/bench_bridges.py`` uses 48490-48499 and 18890-18899). A port is free when
probed; asyncua binds it seconds later, after building its address space.
"""
from __future__ import annotations

import os
from pathlib import Path
import socket
import sys

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _range(name: str, default: str) -> range:
    text = os.environ.get(name, default)
    low, _, high = text.partition('-')
    return range(int(low), int(high or low) + 1)


def free_port(name: str, default: str) -> int:
    """A loopback TCP port of the range ``name`` that nothing listens on now."""
    for port in _range(name, default):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
            try:
                sock.bind(('127.0.0.1', port))
            except OSError:
                continue
            return port
    pytest.fail(f'no free port in {name}={os.environ.get(name, default)}')


def opcua_port() -> int:
    """A free port for an OPC UA server."""
    return free_port('FAE_OPCUA_PORTS', '48400-48489')


def mqtt_port() -> int:
    """A free port for an MQTT broker."""
    return free_port('FAE_MQTT_PORTS', '18830-18889')


@pytest.fixture
def program_root(tmp_path: Path) -> Path:
    """A program root with two small programs (the fake service only checks they exist)."""
    root = tmp_path / 'programs'
    root.mkdir()
    (root / 'a.ngc').write_text('G1 X10 F1000\nM2\n')
    (root / 'b.ngc').write_text('G1 Y10 F1000\nM2\n')
    (tmp_path / 'outside.ngc').write_text('M2\n')
    return root
