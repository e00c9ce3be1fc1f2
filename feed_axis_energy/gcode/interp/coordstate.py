"""What :class:`~.coords.Coords` and its mixins (:mod:`.tools`, :mod:`.stored`) share, declared
once for the type checker (as :mod:`.state` does for the interpreter); imported only under
``typing.TYPE_CHECKING``, so nothing here changes a class, an instance or the import time.
"""
from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from typing import Protocol

from ..settings import ToolSpec

__all__ = ['CoordsState', 'ParamStore', 'Vec3']

Vec3 = tuple[float, float, float]


class ParamStore(Protocol):
    """The numbered parameters: ``Parameters`` of the front's reader, or ``ParamTable``."""

    def get(self, n: int, /) -> float: ...

    def set(self, n: int, value: float, /) -> None: ...


class CoordsState:
    """The state of :class:`~.coords.Coords` its mixins (:mod:`.tools`, :mod:`.stored`) use,
    and the methods they call on it (a plain class, as :class:`InterpreterState`)."""

    params: ParamStore
    tools: dict[int, ToolSpec]
    system: int
    g5x: Vec3
    g92: Vec3
    tlo: Vec3
    offset: Vec3
    rotation_deg: float
    cos: float
    sin: float
    selected_tool: int
    loaded_tool: int
    strict_tools: bool
    on_missing_tool: Callable[[int], None] | None
    home_used: bool

    @abstractmethod
    def _update(self) -> None: ...

    @abstractmethod
    def to_program(self, machine: Vec3) -> Vec3: ...
