"""Commands of the machine cell: ``serve`` (the graph as a job service on OPC UA and MQTT)
and ``cell-client`` (an OPC UA client that submits jobs and prints their results).

Thin shells like the rest of :mod:`feed_axis_energy.cli` (``add_parser``, ``run``); their
own folder because they form one concern (docs/cell.md) and ``cli/`` is full.
"""

__all__: list[str] = []
