"""What the interpreter's mixins share, declared once for the type checker.

:class:`~.interpreter.Interpreter` is built from mixins (:mod:`.motion`, :mod:`.modes`,
:mod:`.comp`, :mod:`.frames`, :mod:`..expand.splines`) that read and write its state and
call each other's methods. :class:`InterpreterState` names that state (set up in
``Interpreter.__init__``) and the methods one mixin takes from another. It is imported only
under ``typing.TYPE_CHECKING``: at run time each mixin's base is ``object``, so nothing here
changes a class, an instance or the import time. Its methods are abstract: mypy checks that
the interpreter implements them all.
"""
from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from typing import Any, NoReturn, Protocol

from ..dialect import Dialect
from ..expand.cutter import CutterComp
from ..expand.cycles import CycleMemory
from ..expand.nurbs import NurbsState
from ..program import Move
from ..read.block import Block
from ..settings import ToolSpec
from .coordstate import Vec3
from .coords import Coords
from .rotary import RotaryAxes

__all__ = ['InterpreterState', 'Lines']


class Lines(Protocol):
    """The source lines an error is shown from: a list, or the streaming path's stand-in."""

    def __getitem__(self, index: int, /) -> str: ...


class InterpreterState:
    """The interpreter's modal state and the methods its mixins call on one another (a
    plain class, not a Protocol: mypy would take a protocol's attributes as abstract and
    infer them anew from each mixin's assignments)."""

    file: str
    arc_tol: float | None
    arc_quick: float
    pos: Vec3
    motion: int | None
    plane: int
    scale: float
    absolute: bool
    arc_absolute: bool
    inverse_time: bool
    feed_per_rev: float | None
    feed: float | None
    exact: bool
    coord: int
    moves: list[Move]
    warnings: list[str]
    lineno: int
    lines: Lines | None
    ended: bool
    g_cache: dict[str | float, tuple[str, Any, int]]
    g43_lineno: int
    home: Vec3 | None
    coords: Coords
    frame: Vec3
    rotated: bool
    coord_line: int
    coord_todo: dict[str, object]
    retract: int
    cycle_memory: CycleMemory
    series: bool
    comp: CutterComp
    routing: bool
    comp_code: int | None
    pending_lineno: int
    tool_change: bool
    tools: dict[int, ToolSpec]
    allow_no_feed: bool
    tool_selected: int
    tool_loaded: int
    on_tool: Callable[[int], None] | None
    spindle: int
    p_unit: float
    dialect: Dialect
    src: Block | None
    io_lineno: int
    user_m_lineno: int
    warned: set[str]
    ignore_axes: frozenset[str]
    rpm: float
    polar_line: int
    polar_inc: tuple[float, float]
    d_selected: int | None
    nurbs: NurbsState
    rotary: RotaryAxes | None

    # interpreter.py
    @abstractmethod
    def fail(self, msg: str, letter: str, *, value: float | None = None,
             nth: int = 0) -> NoReturn: ...

    @abstractmethod
    def num(self, letter: str, text: str | float) -> float: ...

    @abstractmethod
    def first_axis(self, d: dict[str, str | float]) -> str: ...

    @abstractmethod
    def missing_tool(self, number: int) -> None: ...

    @abstractmethod
    def refuse_rotary(self, what: str) -> None: ...

    @abstractmethod
    def rotary_move(self, m: Move) -> Move: ...

    # comp.py
    @abstractmethod
    def emit(self, move: Move) -> None: ...

    @abstractmethod
    def route(self, move: Move) -> None: ...

    @abstractmethod
    def end_series(self) -> None: ...

    # motion.py
    @abstractmethod
    def target(self, d: dict[str, str | float]) -> Vec3: ...

    @abstractmethod
    def feed_for(self, d: dict[str, str | float], length: float, explicit: bool) -> float: ...

    # frames.py
    @abstractmethod
    def offset(self) -> Vec3: ...

    @abstractmethod
    def rotated_target(self, d: dict[str, str | float]) -> Vec3: ...

    @abstractmethod
    def probe_result(self) -> None: ...

    # expand/splines.py
    @abstractmethod
    def nurbs_close(self) -> None: ...

    @abstractmethod
    def nurbs_end(self, d: dict[str, str | float]) -> None: ...
