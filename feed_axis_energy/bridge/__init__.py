"""The machine cell's bridges: an OPC UA server and an MQTT bridge over a job service.

Pure Python, no ROS: the bridges speak to the machine's jobs only through the
:class:`JobService` protocol (:mod:`.service`), which a thin node adapts to the graph's job
interface. :mod:`.requests` checks what clients send before the service sees it;
:mod:`.security` decides who may connect to the OPC UA server (:mod:`.opcua`);
:mod:`.topics` is the MQTT topic tree and its JSON, :mod:`.measured` the check of live
measured drive data arriving over MQTT, :mod:`.mqtt` the client that joins them;
:mod:`.sparkplug` publishes the same as a Sparkplug B edge node, with the protobuf payloads
of :mod:`.sparkplug_payload`;
:mod:`.graphjobs` is the job service on the graph's job topics (the ``opcua_bridge`` node is
its ROS shell); :mod:`.logbound` keeps a peer that fails again and again from flooding the
log. The address space, topic tree, job states and security are contracts: docs/cell.md.
"""
from .measured import (DROP_REASONS, MAX_PAYLOAD_BYTES, MeasuredInput, MeasuredSample,
                       parse_measured, QUANTITIES)
from .mqtt import MqttBridge, MqttSettings, tcp_no_delay
from .opcua import (BROWSE_PATHS, ENERGY_NAMES, J_PER_WH, NAMESPACE_URI, OpcUaBridge,
                    OpcUaSettings, OpcUaThread, UNECE_NAMESPACE, unece_unit_id, UNITS)
from .requests import (check_job_id, check_load_kg, check_program, MAX_JOB_ID_CHARS,
                       MAX_LOAD_KG, MAX_PROGRAM_CHARS)
from .graphjobs import GraphJobService, MEASURED_LIVE_KEYS, measured_live_payload, service_result
from .security import (is_loopback, OpcUaSecurity, PasswordUsers, read_users_file,
                       security_plan, SecurityPlan)
from .service import (AxisPower, FINAL_STATES, JOB_STATES, JobService, Listener, LiveSample,
                      RESULT_KEYS, result_summary, ResultSummary, ServiceEvent, StateChange)
from .sparkplug import (device_metrics, REBIRTH_METRIC, SPARKPLUG_NAMESPACE, SparkplugBridge,
                        SparkplugSettings, SparkplugTopics)
from .sparkplug_payload import (decode_sparkplug, encode_sparkplug, MAX_DECODED_BYTES,
                                SpDataType, SpMetric, SpPayload)
from .topics import (DEFAULT_PREFIX, POWER_KEYS, power_payload, result_payload, RETAINED,
                     STATE_KEYS, state_payload, STATUS_KEYS, status_payload, TopicTree)

__all__ = [
    'AxisPower', 'BROWSE_PATHS', 'check_job_id', 'check_load_kg', 'check_program',
    'decode_sparkplug', 'DEFAULT_PREFIX', 'device_metrics', 'DROP_REASONS', 'ENERGY_NAMES',
    'encode_sparkplug', 'FINAL_STATES', 'GraphJobService', 'MAX_DECODED_BYTES',
    'REBIRTH_METRIC', 'SPARKPLUG_NAMESPACE', 'SparkplugBridge', 'SparkplugSettings',
    'SparkplugTopics', 'SpDataType', 'SpMetric', 'SpPayload', 'tcp_no_delay',
    'is_loopback', 'MEASURED_LIVE_KEYS', 'measured_live_payload', 'read_users_file',
    'service_result',
    'J_PER_WH', 'JOB_STATES', 'JobService', 'Listener', 'LiveSample', 'MAX_JOB_ID_CHARS',
    'MAX_LOAD_KG', 'MAX_PAYLOAD_BYTES', 'MAX_PROGRAM_CHARS', 'MeasuredInput', 'MeasuredSample',
    'MqttBridge', 'MqttSettings', 'NAMESPACE_URI', 'OpcUaBridge', 'OpcUaSecurity',
    'OpcUaSettings', 'OpcUaThread', 'parse_measured', 'PasswordUsers', 'POWER_KEYS',
    'power_payload', 'QUANTITIES', 'RESULT_KEYS', 'result_payload', 'result_summary',
    'ResultSummary', 'RETAINED', 'security_plan', 'SecurityPlan', 'ServiceEvent', 'STATE_KEYS',
    'state_payload', 'StateChange', 'STATUS_KEYS', 'status_payload', 'TopicTree',
    'UNECE_NAMESPACE', 'unece_unit_id', 'UNITS',
]
