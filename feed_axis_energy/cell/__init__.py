"""Jobs in the machine cell, without ROS: what a job is, its states, its result.

A cell controller asks the graph to run a program as a *job*. This package holds everything
about jobs that does not depend on how the request arrives (a ROS topic today; an OPC UA
method or an MQTT message later): the checked request (:mod:`.spec`: job id, a program that
must lie inside the configured root, load, optional machine and overrides), the state
machine (:mod:`.states`), the per-job result and the store of the last N (:mod:`.result`),
the board a shell drives (:mod:`.board`: start, abort, state, result by id) and the JSON of
the job topics (:mod:`.wire`). The nodes in :mod:`feed_axis_energy.nodes` are its ROS
shell (docs/nodes.md, "Jobs").
"""
from .board import JobBoard, JobSnapshot
from .result import ELECTRICAL_KEYS, EnergyReport, JobResult, RESULT_STATUSES, ResultStore
from .spec import (check_job_id, check_load, file_sha256, job_machine, JobLimits, JobSpec,
                   MAX_JOB_ID_CHARS, MAX_OVERRIDES, parse_job_request, resolve_inside)
from .states import ACTIVE, check_transition, JobState, TERMINAL, TRANSITIONS
from .wire import Command, COMMANDS, dumps, MAX_COMMAND_BYTES, parse_command, reply

__all__ = [
    'ACTIVE', 'check_job_id', 'check_load', 'check_transition', 'Command', 'COMMANDS', 'dumps',
    'ELECTRICAL_KEYS', 'EnergyReport', 'file_sha256', 'job_machine', 'JobBoard', 'JobLimits',
    'JobResult', 'JobSnapshot', 'JobSpec', 'JobState', 'MAX_COMMAND_BYTES', 'MAX_JOB_ID_CHARS',
    'MAX_OVERRIDES', 'parse_command', 'parse_job_request', 'reply', 'resolve_inside',
    'RESULT_STATUSES', 'ResultStore', 'TERMINAL', 'TRANSITIONS',
]
