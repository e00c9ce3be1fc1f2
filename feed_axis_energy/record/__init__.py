"""Everything rosbag2/MCAP: writing, reading and checking recordings.

The recorded form of a simulation (:mod:`.recording`: topics, units, plot topics, standstill
thinning), the bag writer (:mod:`.bagwrite` on :mod:`.mcapstream`), the crash-safe writer of
the node graph (:mod:`.crashsafe`), CDR encoding (:mod:`.cdr`), QoS (:mod:`.qos`), reading and
checks (:mod:`.bagio`, :mod:`.bagcheck`, :mod:`.mcapcheck`, :mod:`.plotread`) and the wall-clock
start of stamps (:mod:`.starttime`).
"""
from .bagio import bag_topics, DIAGNOSTIC_ARRAY, typestore
from .bagwrite import StreamBagWriter
from .cdr import BLOCK_ENERGY_PER_MESSAGE
from .crashsafe import ChunkedBagWriter
from .mcapcheck import check_mcap
from .plottopics import (block_energy_joint_state, DEFAULT_PLOT_RATE_HZ, JOINT_STATE,
                         joint_state_rows, PlotDecimator, TOPIC_PLOT_AXES,
                         TOPIC_PLOT_BLOCK_ENERGY, TOPIC_PLOT_POWER)
from .recording import SimulationBagWriter, write_simulation_bag
from .starttime import check_end, MAX_STAMP_NS, parse_start_time, restamp

__all__ = [
    'bag_topics', 'block_energy_joint_state', 'BLOCK_ENERGY_PER_MESSAGE', 'check_end',
    'check_mcap',    'ChunkedBagWriter', 'DEFAULT_PLOT_RATE_HZ', 'DIAGNOSTIC_ARRAY', 'JOINT_STATE',
    'joint_state_rows', 'MAX_STAMP_NS', 'parse_start_time', 'PlotDecimator', 'restamp',
    'SimulationBagWriter', 'StreamBagWriter', 'TOPIC_PLOT_AXES', 'TOPIC_PLOT_BLOCK_ENERGY',
    'TOPIC_PLOT_POWER', 'typestore', 'write_simulation_bag',
]
