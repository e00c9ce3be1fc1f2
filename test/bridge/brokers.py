"""MQTT brokers for the bridge tests: mosquitto in a child process, amqtt in a thread.

``mosquitto`` (Debian package) is the real broker the tests want; it runs with a
configuration written to the test's temporary folder (one loopback listener, anonymous, no
persistence, log to a file there, ``set_tcp_nodelay`` as docs/cell.md advises). ``amqtt``
is the in-process fallback where mosquitto is missing: its broker runs in an asyncio loop
of its own thread.
"""
from __future__ import annotations

import asyncio
from contextlib import contextmanager
from pathlib import Path
import shutil
import socket
import subprocess
import threading
import time
from typing import Iterator

MOSQUITTO_PATHS = ('/usr/sbin/mosquitto', '/usr/bin/mosquitto')


def mosquitto_binary() -> str | None:
    """The mosquitto executable, or None."""
    found = shutil.which('mosquitto')
    if found:
        return found
    return next((p for p in MOSQUITTO_PATHS if Path(p).is_file()), None)


def _wait_listening(port: int, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        with socket.socket() as sock:
            sock.settimeout(0.2)
            if sock.connect_ex(('127.0.0.1', port)) == 0:
                return True
        time.sleep(0.05)
    return False


@contextmanager
def mosquitto(tmp: Path, port: int) -> Iterator[str]:
    """Run mosquitto on ``127.0.0.1:port`` for the ``with`` block; yields 'mosquitto'."""
    binary = mosquitto_binary()
    assert binary is not None
    tmp.mkdir(parents=True, exist_ok=True)
    conf = tmp / 'mosquitto.conf'
    log = tmp / 'mosquitto.log'
    conf.write_text(f'listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n'
                    f'log_dest file {log}\nlog_type error\nlog_type warning\n'
                    'max_queued_messages 100000\nset_tcp_nodelay true\n')
    log.touch()
    log.chmod(0o666)   # as root mosquitto drops to its own user before opening the log
    tmp.chmod(0o755)
    proc = subprocess.Popen([binary, '-c', str(conf)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    try:
        if not _wait_listening(port, 10.0):
            proc.kill()
            err = proc.communicate(timeout=5)[1].decode(errors='replace')
            raise RuntimeError(f'mosquitto did not listen on {port}: {err} '
                               f'{log.read_text(errors="replace")}')
        yield 'mosquitto'
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


@contextmanager
def amqtt_broker(port: int) -> Iterator[str]:
    """Run amqtt's broker on ``127.0.0.1:port`` in a thread; yields 'amqtt'."""
    from amqtt.broker import Broker
    from amqtt.contexts import BrokerConfig, ListenerConfig

    loop = asyncio.new_event_loop()
    started = threading.Event()
    holder: dict[str, object] = {}

    async def start() -> None:
        config = BrokerConfig(
            listeners={'default': ListenerConfig(bind=f'127.0.0.1:{port}')},
            plugins={'amqtt.plugins.authentication.AnonymousAuthPlugin':
                     {'allow_anonymous': True}})
        broker = Broker(config)
        await broker.start()
        holder['broker'] = broker

    def run() -> None:
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(start())
        except BaseException as exc:   # reported to the test below
            holder['error'] = exc
        started.set()
        if 'broker' in holder:
            loop.run_forever()

    thread = threading.Thread(target=run, name='amqtt', daemon=True)
    thread.start()
    started.wait(30)
    if 'error' in holder or not _wait_listening(port, 10.0):
        raise RuntimeError(f'amqtt did not start on {port}: {holder.get("error")}')
    try:
        yield 'amqtt'
    finally:
        broker = holder['broker']
        future = asyncio.run_coroutine_threadsafe(broker.shutdown(), loop)  # type: ignore
        try:
            future.result(timeout=10)
        finally:
            loop.call_soon_threadsafe(loop.stop)
            thread.join(10)
            loop.close()
