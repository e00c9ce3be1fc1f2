"""``opcua_bridge``: the graph's jobs on OPC UA (and MQTT), measured drive data in.

A thin shell (docs/cell.md): :class:`feed_axis_energy.bridge.GraphJobService` is the job
service on the job topics (``job/command`` out; ``job/reply``, ``job/state``, ``job/result``,
``job/live`` in), :class:`feed_axis_energy.bridge.OpcUaThread` serves it on OPC UA and, when
``mqtt_host`` is set, :class:`feed_axis_energy.bridge.MqttBridge` publishes it on MQTT and
takes live measured drive data from ``<prefix>/<machine>/measured/<axis>``; with
``sparkplug`` (``GROUP_ID/EDGE_NODE_ID``) :class:`feed_axis_energy.bridge.SparkplugBridge`
also publishes it as a Sparkplug B edge node with the machine as its device; each accepted
sample is republished on ``measured/live`` (``std_msgs/String``, JSON ``{"axis", "stamp",
"quantity", "value"}``, docs/nodes.md). Bad parameters, a port in use or a broker that does
not answer end the node at start-up with one line and exit code 1. Once the OPC UA server
listens and the graph's job topics are matched the node logs ``ready: ...`` with the
endpoints (``feed-axis-energy serve`` waits for that line). Stopping the node (or losing a
client or the broker) never stops a job.
"""
from __future__ import annotations

from pathlib import Path
import sys
import time

from rclpy.node import Node
from std_msgs.msg import String

from feed_axis_energy.bridge import (GraphJobService, measured_live_payload, MqttBridge,
                                     MqttSettings, OpcUaSecurity, OpcUaSettings, OpcUaThread,
                                     read_users_file, SparkplugBridge, SparkplugSettings,
                                     SparkplugTopics, TopicTree)
from feed_axis_energy.machine import load_machine
from feed_axis_energy.nodes.qos import command_qos, job_qos, measured_live_qos
from feed_axis_energy.nodes.runner import declare, guard_parameters, run, StartupError, \
    steady_timer
from feed_axis_energy.paths import default_machine

__all__ = ['OpcUaBridgeNode', 'main']

_MATCH_SETTLE_S = 0.5


class OpcUaBridgeNode(Node):
    """The job service on the job topics, served on OPC UA and MQTT."""

    def __init__(self, **kwargs) -> None:
        super().__init__('opcua_bridge', **kwargs)
        self.exit_code: int | None = None
        machine = declare(self, 'machine', '', 'machine config YAML: its axes are the '
                          'per-axis OPC UA nodes and the accepted measured axes')
        host = declare(self, 'opcua_host', '127.0.0.1',
                       'address the OPC UA server binds (off loopback: certificate, key and '
                       'users required)')
        port = declare(self, 'opcua_port', 4840, 'TCP port of the OPC UA server')
        cert = declare(self, 'opcua_certificate', '', 'server certificate (DER or PEM)')
        key = declare(self, 'opcua_private_key', '', 'its private key (PEM)')
        users = declare(self, 'opcua_users_file', '', 'users: one name:password a line')
        trusted = declare(self, 'opcua_trusted_clients', '',
                          "client certificates accepted, comma-separated files ('': any)")
        max_load = declare(self, 'max_load_kg', 10000.0, 'largest LoadKg accepted [kg]')
        mqtt_host = declare(self, 'mqtt_host', '', "MQTT broker; '' for no MQTT bridge")
        mqtt_port = declare(self, 'mqtt_port', 1883, 'TCP port of the MQTT broker')
        prefix = declare(self, 'mqtt_prefix', 'feed_axis_energy', 'first MQTT topic levels')
        name = declare(self, 'mqtt_machine', 'machine', 'machine name, one MQTT topic level')
        sparkplug = declare(self, 'sparkplug', '',
                            "GROUP_ID/EDGE_NODE_ID: also publish as a Sparkplug B edge node "
                            "(device: mqtt_machine) on the MQTT broker; '' for none")
        reply_s = declare(self, 'reply_timeout_s', 10.0,
                          'longest wait for the graph to answer a command [s]')
        keep = declare(self, 'keep_results', 100, 'job results kept for GetResult')
        guard_parameters(self, {})
        axes = [a.name for a in load_machine(machine or default_machine()).axes]
        try:
            security = OpcUaSecurity(
                certificate=Path(cert) if cert else None,
                private_key=Path(key) if key else None,
                users=read_users_file(Path(users)) if users else {},
                trusted_clients=tuple(Path(p.strip()) for p in trusted.split(',')
                                      if p.strip()))
            settings = OpcUaSettings(host=host, port=port, security=security,
                                     max_load_kg=max_load, call_timeout_s=reply_s + 2.0)
            mqtt = MqttSettings(host=mqtt_host, port=mqtt_port,
                                topics=TopicTree(prefix=prefix, machine=name),
                                axes=tuple(axes)) if mqtt_host else None
            if sparkplug and not mqtt_host:
                raise ValueError('sparkplug needs mqtt_host: the edge node uses that broker')
            spb = SparkplugSettings(host=mqtt_host, port=mqtt_port,
                                    topics=SparkplugTopics.parse(sparkplug, device_id=name)) \
                if sparkplug else None
        except (TypeError, ValueError) as err:
            raise StartupError(str(err)) from None
        self.pub_command = self.create_publisher(String, 'job/command', command_qos())
        self.pub_measured = self.create_publisher(String, 'measured/live', measured_live_qos())
        self.service = GraphJobService(axes, self._send, reply_timeout_s=reply_s, keep=keep)
        self.create_subscription(String, 'job/reply',
                                 lambda m: self.service.on_reply(m.data), command_qos())
        self.create_subscription(String, 'job/state', self._on_state, job_qos())
        self.create_subscription(String, 'job/result',
                                 lambda m: self.service.on_result(m.data), job_qos())
        self.create_subscription(String, 'job/live',
                                 lambda m: self.service.on_live(m.data), command_qos())
        self._seen_state = False
        self._matched_at: float | None = None
        self._ready = False
        self.opcua = OpcUaThread(self.service, settings)
        self.mqtt: MqttBridge | None = None
        self.sparkplug: SparkplugBridge | None = None
        try:
            self.opcua.start()
        except Exception as err:   # noqa: B902 - asyncua's bind/cert failures: one clear line
            raise StartupError(f'cannot start the OPC UA server at {settings.endpoint}: '
                               f'{type(err).__name__}: {err}') from None
        if mqtt is not None:
            try:
                self.mqtt = MqttBridge(self.service, mqtt, on_measured=self._on_measured)
                self.mqtt.start()
            except Exception as err:   # noqa: B902 - a start-up failure: one line, exit 1
                self.mqtt = None
                self.opcua.stop()
                raise StartupError(str(err)) from None
        if spb is not None:
            try:
                self.sparkplug = SparkplugBridge(self.service, spb)
                self.sparkplug.start()
            except Exception as err:   # noqa: B902 - a start-up failure: one line, exit 1
                self.sparkplug = None
                self.close()
                raise StartupError(str(err)) from None
        self._where = [f'OPC UA {settings.endpoint}']
        if mqtt is not None:
            self._where.append(f'MQTT {mqtt.host}:{mqtt.port} topics {mqtt.topics.base}/#')
        if spb is not None:
            self._where.append(f'Sparkplug B {spb.topics.device("DDATA")} (spBv1.0/'
                               f'{spb.topics.group_id}/#)')
        steady_timer(self, 0.1, self._tick)

    def _send(self, text: str) -> None:
        """Publish one command once the graph's command reader is matched (any thread)."""
        end = time.monotonic() + self.service.reply_timeout_s
        while self.pub_command.get_subscription_count() < 1 and time.monotonic() < end:
            time.sleep(0.01)
        self.pub_command.publish(String(data=text))

    def _on_state(self, msg: String) -> None:
        self._seen_state = True
        self.service.on_state(msg.data)

    def _on_measured(self, sample) -> None:
        """An accepted measured sample (MQTT network thread) -> ``measured/live``."""
        self.pub_measured.publish(String(data=measured_live_payload(sample)))

    def _tick(self) -> None:
        self.service.tick()
        if self._ready:
            return
        matched = (self._seen_state and self.pub_command.get_subscription_count() >= 1
                   and self.count_publishers(self.resolve_topic_name('job/reply')) >= 1)
        if not matched:
            self._matched_at = None
            return
        if self._matched_at is None:
            self._matched_at = time.monotonic()
        elif time.monotonic() - self._matched_at >= _MATCH_SETTLE_S:
            # discovery is per direction: the settle lets the graph match us back
            self._ready = True
            self.get_logger().info(f'ready: {"; ".join(self._where)}')

    def close(self) -> None:
        """Stop MQTT (offline, retained; Sparkplug NDEATH) and the OPC UA server.

        The graph's job goes on.
        """
        if self.sparkplug is not None:
            self.sparkplug.stop()
            self.sparkplug = None
        if self.mqtt is not None:
            self.mqtt.stop()
            self.mqtt = None
        self.opcua.stop()


def main(args: list[str] | None = None) -> None:
    """Run the node (``ros2 run feed_axis_energy opcua_bridge``)."""
    sys.exit(run(OpcUaBridgeNode, args, name='opcua_bridge'))


if __name__ == '__main__':
    main()
