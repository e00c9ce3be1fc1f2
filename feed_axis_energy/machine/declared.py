"""The ``effects`` list of a machine file: catalog effects the model declares.

Split from :mod:`.machine` (its own seam: the catalog check and the YAML form). Each entry
``{id, axis, params, calibrated}`` adds an effect of the catalog (:mod:`.effects`,
``docs/effects.md``) to the named axis (every axis when ``axis`` is left out) after the
braking rule; parameters left out take the catalog default.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .calibrated import calibrated_from_value, CalibratedRange
from ..configcheck import check_choice, check_float, check_mapping
from ..errors import ConfigError, describe

__all__ = ['DeclaredEffect', 'effects_from_value', 'effects_to_list']


@dataclass(frozen=True)
class DeclaredEffect:
    """A catalog effect the machine model declares (see :mod:`.effects`).

    Attributes
    ----------
    id
        Catalog id (``'load_friction'``).
    axis
        The axis it acts on, or ``None`` for every axis.
    params
        ``(name, value)`` pairs in SI units; parameters not given take the catalog default.
    calibrated
        Speeds, loads and positions it was identified on (``analyze --out-machine``), or
        ``None``.
    """

    id: str
    axis: str | None = None
    params: tuple[tuple[str, float], ...] = ()
    calibrated: CalibratedRange | None = None

    @property
    def values(self) -> dict[str, float]:
        """Parameters as a dict."""
        return dict(self.params)


def effects_from_value(value: Any, axis_names: tuple[str, ...], *,
                       file: str) -> tuple[DeclaredEffect, ...]:
    """The ``effects`` list of a machine file, checked against the catalog.

    Raises
    ------
    ConfigError
        Not a list, an unknown effect, axis or parameter, or a value out of its bounds.
    """
    if value is None:
        return ()
    if not isinstance(value, list):
        msg = f'expected a list of effects, got {describe(value)}'
        raise ConfigError(msg, file=file, key='effects')
    # the catalog is imported only for a machine that declares effects (start-up time)
    from ..effects import EFFECTS
    out = []
    for i, item in enumerate(value):
        key = f'effects[{i}]'
        item = check_mapping(item, file=file, key=key,
                             allowed=('id', 'axis', 'params', 'calibrated'))
        effect_id = item.get('id')
        if not isinstance(effect_id, str) or effect_id not in EFFECTS:
            msg = f'unknown effect {describe(effect_id)}; expected one of {", ".join(EFFECTS)}'
            raise ConfigError(msg, file=file, key=f'{key}.id')
        cls = EFFECTS[effect_id]
        if not cls.machine_property:
            msg = (f'effect {effect_id!r} describes how a measured and a simulated record line '
                   'up, not the machine; compare estimates it for every run')
            raise ConfigError(msg, file=file, key=f'{key}.id')
        axis = check_choice(item, 'axis', axis_names + (None,), file=file, key=key, default=None)
        params_d = check_mapping(item.get('params', {}) or {}, file=file,
                                 key=f'{key}.params', allowed=cls.param_names())
        params = tuple((name, check_float(params_d, name, file=file, key=f'{key}.params',
                                          minimum=-1.0e12, strict=False, maximum=1.0e12))
                       for name in cls.param_names() if name in params_d)
        try:
            cls.resolve(dict(params))      # the physical bounds (a negative loss, ...)
        except ConfigError as err:
            raise ConfigError(err.reason, file=file, key=f'{key}.params') from None
        calibrated = calibrated_from_value(item.get('calibrated'), file=file,
                                           key=f'{key}.calibrated')
        out.append(DeclaredEffect(id=effect_id, axis=axis, params=params,
                                  calibrated=calibrated))
    return tuple(out)


def effects_to_list(effects: tuple[DeclaredEffect, ...]) -> list[dict[str, Any]]:
    """The YAML form of declared effects (:func:`effects_from_value` of it gives them back)."""
    return [{'id': e.id, 'axis': e.axis, 'params': {n: float(v) for n, v in e.params}}
            | ({} if e.calibrated is None else {'calibrated': e.calibrated.to_dict()})
            for e in effects]
