"""``feed-axis-energy serve`` end to end (issue 22, "Done when"): the graph, the OPC UA server
and a real MQTT broker (mosquitto) on loopback; two jobs through OPC UA ``StartJob``, one
through the ROS job interface, a fourth aborted while it runs; every ended result against
offline ``simulate --json`` of the same program, machine and load; the MQTT result and state
messages and the same results as Sparkplug B metrics (``--mqtt-sparkplug``); measured
samples over MQTT seen on ROS ``measured/live``; hostile clients."""
import asyncio
import json
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import threading
import time

import must_run
import pytest

must_run.import_or_skip('rclpy', 'rclpy')
must_run.import_or_skip('asyncua', 'asyncua')
from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'bridge'))
from brokers import mosquitto, mosquitto_binary  # noqa: E402

PY = sys.executable
NS = 'urn:feed-axis-energy:cell'
SHORT = 'G21 G90 G94 G61\nG0 X0\nG1 X100 F3000\nG4 P0.2\nG1 X80 F3000\n'
XYZ = 'G21 G90 G94 G61\nG1 X120 Y40 Z-20 F6000\nG4 P0.1\nG1 X0 Y0 Z0 F9000\n'
LONG = 'G21 G90 G94 G61\n' + 'G1 X100 F3000\nG1 X0 F3000\n' * 15
MACHINE = 'three_axis_mill_drives.yaml'
BASE = 'feed_axis_energy/machine'


def _free_port():
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def _shipped(name):
    from feed_axis_energy.paths import config_dir
    return config_dir() / name


def _offline(program, env, load_kg):
    # --method samples: the graph's results are sums over its samples (as the other node
    # tests compare them)
    out = subprocess.run([PY, '-m', 'feed_axis_energy', 'simulate', str(program), '--json',
                          '--machine', str(_shipped(MACHINE)), '--load-kg', str(load_kg),
                          '--method', 'samples'],
                         env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


class _Mqtt:
    """Subscribes to the whole topic tree and to spBv1.0/#; publishes measured samples."""

    def __init__(self, port):
        import paho.mqtt.client as paho
        self.messages = []
        self.sparkplug = []
        self.lock = threading.Lock()
        subscribed = threading.Event()
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='e2e-watch')
        self.client.on_subscribe = lambda *a: subscribed.set()
        self.client.on_message = self._on_message
        self.client.on_connect = lambda c, *a: c.subscribe(
            [(f'{BASE}/#', 1), ('spBv1.0/#', 1)])
        self.client.connect('127.0.0.1', port)
        self.client.loop_start()
        assert subscribed.wait(10)

    def _on_message(self, client, userdata, message):
        from feed_axis_energy.bridge import decode_sparkplug
        with self.lock:
            if message.topic.startswith('spBv1.0/'):
                self.sparkplug.append((message.topic, decode_sparkplug(message.payload)))
            else:
                self.messages.append((message.topic, json.loads(message.payload)))

    def on(self, topic):
        with self.lock:
            return [m for t, m in self.messages if t == f'{BASE}/{topic}']

    def close(self):
        self.client.disconnect()
        self.client.loop_stop()


class _Ros:
    """The ROS job interface and measured/live, in a context of its own."""

    def __init__(self, context):
        import rclpy
        from std_msgs.msg import String
        from feed_axis_energy.nodes.qos import command_qos, job_qos, measured_live_qos
        from feed_axis_energy.nodes.runner import make_executor
        self.String = String
        self.node = rclpy.create_node('e2e_client', context=context)
        self.ex = make_executor(context=context)
        self.ex.add_node(self.node)
        self.replies, self.results, self.measured = {}, {}, []
        self.pub = self.node.create_publisher(String, 'job/command', command_qos())
        self.node.create_subscription(String, 'job/reply', self._on_reply, command_qos())
        self.node.create_subscription(String, 'job/result', self._on_result, job_qos())
        self.node.create_subscription(String, 'measured/live',
                                      lambda m: self.measured.append(json.loads(m.data)),
                                      measured_live_qos())

    def _on_reply(self, msg):
        d = json.loads(msg.data)
        self.replies[d['request_id']] = d

    def _on_result(self, msg):
        d = json.loads(msg.data)
        self.results[d['job_id']] = d

    def spin_until(self, cond, timeout_s, what):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if cond():
                return
            self.ex.spin_once(timeout_sec=0.05)
        raise AssertionError(f'timed out waiting for {what}')

    def command(self, request_id, **body):
        self.spin_until(lambda: self.pub.get_subscription_count() >= 1
                        and self.node.count_publishers('job/reply') >= 1, 30, 'the graph')
        time.sleep(0.5)   # the other direction of discovery
        self.pub.publish(self.String(data=json.dumps({'request_id': request_id, **body})))
        self.spin_until(lambda: request_id in self.replies, 30, f'reply {request_id}')
        return self.replies[request_id]

    def close(self):
        self.ex.shutdown()
        self.node.destroy_node()


async def _opcua_client(endpoint):
    from asyncua import Client
    client = Client(endpoint, timeout=30)
    await client.connect()
    idx = await client.get_namespace_index(NS)
    root = await client.nodes.objects.get_child([f'{idx}:FeedAxisEnergy'])
    jobs = await root.get_child(f'{idx}:Jobs')
    results = await root.get_child(f'{idx}:Results')
    return client, idx, jobs, results


async def _wait_value(node, want, timeout_s, what):
    end = time.monotonic() + timeout_s
    value = None
    while time.monotonic() < end:
        value = await node.read_value()
        if want(value):
            return value
        await asyncio.sleep(0.05)
    raise AssertionError(f'timed out waiting for {what}; last {value!r}')


def _start_serve(root, tmp, env, opcua_port, mqtt_port, extra=()):
    proc = subprocess.Popen(
        [PY, '-m', 'feed_axis_energy', 'serve', '--program-root', str(root),
         '--machine', str(_shipped(MACHINE)), '--opcua-port', str(opcua_port),
         '--mqtt', f'127.0.0.1:{mqtt_port}', '--domain-id', env['ROS_DOMAIN_ID'],
         '--mode', 'realtime', *extra], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True)
    lines = []
    end = time.monotonic() + 120
    while time.monotonic() < end:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if line.startswith('Ctrl-C'):
            threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True).start()
            return proc, lines
    proc.kill()
    raise AssertionError(f'serve not ready: {"".join(lines)}')


def _programs(tmp):
    root = tmp / 'programs'
    root.mkdir()
    (root / 'short.nc').write_text(SHORT)
    (root / 'xyz.nc').write_text(XYZ)
    (root / 'long.nc').write_text(LONG)
    (tmp / 'secret.nc').write_text(SHORT)
    (root / 'link.nc').symlink_to(tmp / 'secret.nc')
    (root / 'null.nc').symlink_to('/dev/null')
    os.mkfifo(root / 'fifo.nc')
    return root


@child_only
def test_serve_runs_jobs_from_opcua_ros_and_mqtt_and_stops_cleanly(tmp_path, node_env,
                                                                   context):
    if mosquitto_binary() is None:
        must_run.skip('mosquitto', 'mosquitto is not installed (apt-get install mosquitto)')
    root = _programs(tmp_path)
    mqtt_port, opcua_port = _free_port(), _free_port()
    with mosquitto(tmp_path / 'broker', mqtt_port):
        watch = _Mqtt(mqtt_port)
        proc, lines = _start_serve(root, tmp_path, node_env, opcua_port, mqtt_port,
                                   extra=('--mqtt-sparkplug', 'cell/serve1'))
        ros = _Ros(context)
        try:
            endpoint = f'opc.tcp://127.0.0.1:{opcua_port}/feed_axis_energy/'
            assert any(endpoint in line for line in lines), lines
            found = asyncio.run(_scenario(endpoint, ros, root, tmp_path))
            _measured(ros, mqtt_port)
        finally:
            ros.close()
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            time.sleep(0.5)
            watch.close()
            print(''.join(lines))
    out = ''.join(lines)
    assert proc.returncode == 0, out
    assert 'stopped by SIGINT; all nodes shut down' in out and 'Traceback' not in out
    results, refusals = found

    # the hostile starts: refused with the reason, nothing started
    for program, reason in refusals.items():
        print(f'{program}: {reason}')
    assert '".." is not allowed' in refusals['../secret.nc']
    assert 'outside the program root' in refusals[str(tmp_path / 'secret.nc')]
    for link in ('link.nc', 'null.nc'):
        assert 'outside the program root' in refusals[link]
        assert 'symbolic link' in refusals[link]
    assert 'FIFO, not a regular file' in refusals['fifo.nc']
    assert "'j4' is running" in refusals['second start']

    # every ended result against offline simulate of the same program, machine and load
    for job, program, load in (('j1', 'short.nc', 5.0), ('j2', 'xyz.nc', 20.0),
                               ('j3', 'short.nc', 2.0)):
        res = results[job]
        ref = _offline(root / program, node_env, load)
        assert res['status'] == 'ended' and res['lost_samples'] == 0, res
        assert res['samples'] == ref['samples'] and res['load_kg'] == load
        assert res['energy_j'] == pytest.approx(ref['energy_j']['total'], rel=1e-9, abs=1e-9)
        assert res['peak_power_w'] == pytest.approx(ref['peak_power_w']['total'], rel=1e-9)
        for axis, value in ref['energy_j'].items():
            if axis != 'total':
                assert res['energy_by_axis_j'][axis] == pytest.approx(value, rel=1e-9)
        assert res['electrical']['supply_energy_j']['total'] == pytest.approx(
            ref['electrical']['supply_energy_j']['total'], rel=1e-9)
        print(f"{job}: energy_j graph {res['energy_j']!r} offline "
              f"{ref['energy_j']['total']!r} relative difference "
              f"{abs(res['energy_j'] / ref['energy_j']['total'] - 1):.2e}")
    assert ros.results['j3']['status'] == 'ended'        # the ROS interface saw its job
    full = _offline(root / 'long.nc', node_env, 0.0)
    aborted = results['j4']
    assert aborted['status'] == 'aborted' and 0 < aborted['samples'] < full['samples']
    assert 0 < aborted['energy_j'] < full['energy_j']['total']

    # MQTT: each job's result (as GetResult answered it) and its states, result first
    mqtt_results = {m['job_id']: m for m in watch.on('job/result')}
    for job in ('j1', 'j2', 'j3', 'j4'):
        got = {k: v for k, v in mqtt_results[job].items() if k != 'stamp'}
        assert got == results[job], job
        states = [m['state'] for m in watch.on('job/state') if m['job_id'] == job]
        final = 'aborted' if job == 'j4' else 'ended'
        assert states[-3:] == ['planning', 'running', final], (job, states)
    topics = [t for t, m in watch.messages]
    for job in ('j1', 'j2', 'j3', 'j4'):
        i_res = next(i for i, (t, m) in enumerate(watch.messages)
                     if t.endswith('job/result') and m['job_id'] == job)
        i_end = next(i for i, (t, m) in enumerate(watch.messages)
                     if t.endswith('job/state') and m['job_id'] == job
                     and m['state'] in ('ended', 'aborted'))
        assert i_res < i_end, job
    powers = watch.on('power')
    assert {m['job_id'] for m in powers} >= {'j1', 'j2', 'j3', 'j4'}
    assert all(m['predicted'] is True for m in powers)
    assert f'{BASE}/status' in topics and watch.on('status')[-1]['online'] is False
    _check_sparkplug(watch.sparkplug, results, powers)


def _check_sparkplug(messages, results, powers):
    """The Sparkplug B edge node of the same run: births, seq, the results, the death."""
    topics = [t for t, _ in messages]
    assert topics[:2] == ['spBv1.0/cell/NBIRTH/serve1', 'spBv1.0/cell/DBIRTH/serve1/machine']
    assert topics[-1] == 'spBv1.0/cell/NDEATH/serve1'       # the clean stop says so
    seqs = [p.seq for _, p in messages[:-1]]
    assert seqs[0] == 0 and all(b == (a + 1) % 256 for a, b in zip(seqs, seqs[1:]))
    names = {m.alias: m.name for m in messages[1][1].metrics}
    values = [{names[m.alias]: m.value for m in p.metrics}
              for t, p in messages if t.endswith('/DDATA/serve1/machine')]
    for job in ('j1', 'j2', 'j3', 'j4'):
        got = next(v for v in values if v.get('Result/JobId') == job)
        assert got['Result/Status'] == results[job]['status']
        for key in ('energy_j', 'duration_s', 'peak_power_w'):
            assert got[f'Result/{key}'] == results[job][key], (job, key)
        for axis, energy in results[job]['energy_by_axis_j'].items():
            assert got[f'Result/{axis}/energy_j'] == energy
    live = [v for v in values if 'Live/JobId' in v]
    assert len(live) == len(powers)
    print(f'Sparkplug B: {len(messages)} messages, {len(live)} live DDATA, seq wrapped '
          f'{seqs.count(0) - 1} time(s)')
    assert all(v['Live/total/power_w'] == p['power_w']['total']
               and v['Live/X/energy_j'] == p['energy_j']['X'] for v, p in zip(live, powers))


async def _scenario(endpoint, ros, root, tmp):
    """Jobs and hostile calls over OPC UA (and one job over ROS); the results by job id."""
    client, idx, jobs, results = await _opcua_client(endpoint)
    state = await jobs.get_child(f'{idx}:State')
    last_id = await results.get_child([f'{idx}:LastJob', f'{idx}:JobId'])
    last_energy = await results.get_child([f'{idx}:LastJob', f'{idx}:EnergyJ'])
    found, refusals = {}, {}

    async def get_result(job):
        ok, text, message = await results.call_method(f'{idx}:GetResult', job)
        assert ok, message
        return json.loads(text)

    try:
        for job, program, load in (('j1', 'short.nc', 5.0), ('j2', 'xyz.nc', 20.0)):
            accepted, message = await jobs.call_method(f'{idx}:StartJob', job, program, load)
            assert accepted, message
            await _wait_value(last_id, lambda v, j=job: v == j, 60, f'{job} ended')
            found[job] = await get_result(job)
            assert await last_energy.read_value() == found[job]['energy_j']
        # a job through the ROS interface, seen on OPC UA as well
        reply = ros.command('r3', command='start', job_id='j3', program='short.nc',
                            load_kg=2.0)
        assert reply['accepted'], reply
        await _wait_value(last_id, lambda v: v == 'j3', 60, 'j3 ended')
        found['j3'] = await get_result('j3')
        ros.spin_until(lambda: 'j3' in ros.results, 30, 'j3 on job/result')

        # hostile programs: outside the root, '..', a symlink out, a FIFO, a device
        for program in ('../secret.nc', str(tmp / 'secret.nc'), 'link.nc', 'fifo.nc',
                        'null.nc'):
            accepted, message = await jobs.call_method(f'{idx}:StartJob', 'h1', program, 0.0)
            assert not accepted, program
            refusals[program] = message
        assert await state.read_value() == 'ended'

        # a long job started by a client that then disconnects: it goes on
        other, oidx, ojobs, _ = await _opcua_client(endpoint)
        accepted, message = await ojobs.call_method(f'{oidx}:StartJob', 'j4', 'long.nc', 0.0)
        assert accepted, message
        await _wait_value(state, lambda v: v == 'running', 30, 'j4 running')
        await other.disconnect()
        progress = await jobs.get_child(f'{idx}:Progress')
        first = await _wait_value(progress, lambda v: v > 0, 30, 'progress')
        await asyncio.sleep(1.5)
        assert await state.read_value() == 'running'
        assert await progress.read_value() > first
        line = await (await jobs.get_child(f'{idx}:ActiveLine')).read_value()
        assert line >= 2
        # a second start while it runs: a state error naming the running job
        accepted, message = await jobs.call_method(f'{idx}:StartJob', 'j5', 'short.nc', 0.0)
        assert not accepted
        refusals['second start'] = message
        accepted, message = await jobs.call_method(f'{idx}:AbortJob', 'j4')
        assert accepted, message
        await _wait_value(last_id, lambda v: v == 'j4', 30, 'j4 aborted')
        found['j4'] = await get_result('j4')
        assert await state.read_value() == 'aborted'
    finally:
        await client.disconnect()
    return found, refusals


def _measured(ros, mqtt_port):
    """Samples published on MQTT measured/<axis> arrive on ROS measured/live; junk does not."""
    import paho.mqtt.client as paho
    pub = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='e2e-drive')
    pub.connect('127.0.0.1', mqtt_port)
    pub.loop_start()
    ros.spin_until(lambda: ros.node.count_publishers('measured/live') >= 1, 30,
                   'measured/live publisher')
    time.sleep(0.5)
    stamp = time.time()
    sent = [(axis, stamp + k * 0.001, 10.0 * k + 0.5) for k, axis in
            enumerate(['X', 'Y', 'Z', 'X', 'X'])]
    pub.publish(f'{BASE}/measured/X', b'{"stamp": 1, "value": NaN, "quantity": "power_w"}')
    pub.publish(f'{BASE}/measured/Q', json.dumps(
        {'stamp': stamp, 'value': 1.0, 'quantity': 'power_w'}))
    for axis, t, value in sent:
        info = pub.publish(f'{BASE}/measured/{axis}',
                           json.dumps({'stamp': t, 'value': value, 'quantity': 'power_w'}),
                           qos=1)
        info.wait_for_publish(5)
    ros.spin_until(lambda: len(ros.measured) >= len(sent), 30, 'measured/live samples')
    settle = time.monotonic() + 0.5        # nothing more comes (the junk was dropped)
    ros.spin_until(lambda: time.monotonic() > settle, 5, 'settle')
    pub.disconnect()
    pub.loop_stop()
    assert [(m['axis'], m['value']) for m in ros.measured] == [(a, v) for a, _, v in sent]
    # the sample's own stamp (s since the epoch), not the time it arrived
    for m, (_, t, _) in zip(ros.measured, sent):
        assert m['stamp'] == pytest.approx(t, abs=1e-6)
    assert all(m['quantity'] == 'power_w' for m in ros.measured)


class _Echo:
    """A drive that measures 1.1 times the predicted power: every MQTT ``power`` message of
    the job comes back as ``measured/<axis>`` samples with the same stamp."""

    def __init__(self, port, axes, factor):
        import paho.mqtt.client as paho
        self.axes, self.factor, self.echoed = axes, factor, 0
        ready = threading.Event()
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='e2e-echo')
        self.client.on_subscribe = lambda *a: ready.set()
        self.client.on_message = self._on_power
        self.client.on_connect = lambda c, *a: c.subscribe(f'{BASE}/power', qos=0)
        self.client.connect('127.0.0.1', port)
        self.client.loop_start()
        assert ready.wait(10)

    def _on_power(self, client, userdata, message):
        d = json.loads(message.payload)
        for axis in self.axes:
            client.publish(f'{BASE}/measured/{axis}', json.dumps(
                {'stamp': d['stamp'], 'value': self.factor * d['power_w'][axis],
                 'quantity': 'power_w'}), qos=1)
        self.echoed += 1

    def close(self):
        self.client.disconnect()
        self.client.loop_stop()


@child_only
def test_serve_compares_measured_data_from_mqtt_with_the_running_job(tmp_path, node_env,
                                                                     context):
    """``serve --measured-live --mqtt``: a job started over OPC UA, its predicted power
    echoed at 1.1 times as MQTT measured data; measured_live's final comparison of the job
    names it and shows the energy error (1 - 1.1) / 1.1 = -9.09 %."""
    if mosquitto_binary() is None:
        must_run.skip('mosquitto', 'mosquitto is not installed (apt-get install mosquitto)')
    import rclpy  # noqa: F401
    from std_msgs.msg import String
    from feed_axis_energy.nodes.qos import command_qos
    root = _programs(tmp_path)
    mqtt_port, opcua_port = _free_port(), _free_port()
    with mosquitto(tmp_path / 'broker', mqtt_port):
        echo = _Echo(mqtt_port, ('X', 'Y', 'Z'), 1.1)
        proc, lines = _start_serve(root, tmp_path, node_env, opcua_port, mqtt_port,
                                   extra=('--measured-live',))
        ros = _Ros(context)
        finals = []

        def on_comparison(msg):
            d = json.loads(msg.data)
            if d.get('final'):
                finals.append(d)

        ros.node.create_subscription(String, 'measured/comparison', on_comparison,
                                     command_qos())
        try:
            ros.spin_until(lambda: ros.node.count_publishers('measured/comparison') >= 1, 60,
                           'measured_live')
            time.sleep(1.0)

            async def start():
                client, idx, jobs, _ = await _opcua_client(
                    f'opc.tcp://127.0.0.1:{opcua_port}/feed_axis_energy/')
                try:
                    from asyncua import ua
                    accepted, message = await jobs.call_method(
                        f'{idx}:StartJob', ua.Variant('m1', ua.VariantType.String),
                        ua.Variant('xyz.nc', ua.VariantType.String),
                        ua.Variant(5.0, ua.VariantType.Double))
                    assert accepted, message
                finally:
                    await client.disconnect()

            asyncio.run(start())
            ros.spin_until(lambda: any(f['job_id'] == 'm1' for f in finals), 120,
                           'the final comparison of job m1')
            final = next(f for f in finals if f['job_id'] == 'm1')
            assert echo.echoed >= 10
            assert final['source'] == 'job_live'
            assert final['counters']['samples'] > 0
            measured = final['measured_energy_j']['total']
            predicted = final['predicted_energy_j']['total']
            assert measured > 0
            assert predicted / measured == pytest.approx(1 / 1.1, rel=0.01)
            for name in ('X', 'Y', 'Z', 'total'):
                assert final['energy_error_pct'][name] == pytest.approx(100 * (1 / 1.1 - 1),
                                                                        abs=0.1)
            assert not final['alarm']['active']
        finally:
            echo.close()
            ros.close()
            proc.send_signal(signal.SIGINT)
            assert proc.wait(30) == 0, ''.join(lines)


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The test above, in its own interpreter (see conftest.run_module_in_child)."""
    run_module_in_child(__file__)
