"""The QoS profiles a recording stores per topic, so that ``ros2 bag play`` offers them again.

rosbag2 keeps each topic's offered QoS profiles twice: in ``metadata.yaml``
(``topics_with_message_count[].topic_metadata.offered_qos_profiles``, metadata version 9: a
list of mappings with policy names as lower-case strings) and in the MCAP channel's metadata
(key ``offered_qos_profiles``, the same list as a YAML text). On playback rosbag2 offers the
recorded profile (``Rosbag2QoS::adapt_offer_to_recorded_offers`` in rosbag2_storage's
``qos.cpp``), so a latched (transient-local) topic stays latched for late subscribers. The
profiles here are those of the node graph (``nodes/qos.py``; a test compares them):

* streams (every time series, plot topics included): reliable, keep last 100, transient
  local;
* data published once (``/block_energy``, ``/plot/block_energy``, ``/program/lines``,
  ``/program/end``): reliable, keep last 1, transient local;
* ``/clock``: reliable, keep last 1, volatile.

Durations (deadline, lifespan, liveliness lease) are 0 s 0 ns, "unspecified": the rmw
default, as rclpy's ``QoSProfile`` leaves them.
"""
from __future__ import annotations

import yaml

__all__ = ['STREAM_DEPTH', 'LATCHED_TOPICS', 'topic_qos', 'qos_profile', 'qos_yaml']

STREAM_DEPTH = 100
LATCHED_TOPICS = frozenset({'/block_energy', '/plot/block_energy', '/program/lines',
                            '/program/end'})
_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)


def qos_profile(*, depth: int, durability: str) -> dict:
    """One profile as rosbag2 (metadata version 9) writes it: reliable, keep last ``depth``."""
    zero = {'sec': 0, 'nsec': 0}
    return {'history': 'keep_last', 'depth': int(depth), 'reliability': 'reliable',
            'durability': durability, 'deadline': dict(zero), 'lifespan': dict(zero),
            'liveliness': 'system_default', 'liveliness_lease_duration': dict(zero),
            'avoid_ros_namespace_conventions': False}


def topic_qos(topic: str) -> list[dict]:
    """The offered profiles of a bag topic (``/power`` ...): a list of one profile."""
    name = '/' + topic.lstrip('/')
    if name == '/clock':
        return [qos_profile(depth=1, durability='volatile')]
    if name in LATCHED_TOPICS:
        return [qos_profile(depth=1, durability='transient_local')]
    return [qos_profile(depth=STREAM_DEPTH, durability='transient_local')]


def qos_yaml(profiles: list[dict]) -> str:
    """The profiles as the YAML text of an MCAP channel's ``offered_qos_profiles``."""
    if not profiles:
        return ''
    # keys sorted, as rosbags' writer dumps them (rosbag2 reads either order)
    return yaml.dump(profiles, Dumper=_DUMPER, default_flow_style=False).strip()
