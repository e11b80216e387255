"""Typed config sections: a config dataclass built from a mapping, unknown keys (and, on request, values of
the wrong type) rejected with a message naming them. (The workflow config, scenes and variants: :mod:`anigs.config`.)

A field typed with a config dataclass is a nested section (``masks.vegetation``): its mapping is
parsed into that dataclass, and an unknown key in it fails naming its whole path."""
from __future__ import annotations

import dataclasses
import typing
from typing import Any, ClassVar, Mapping


def reject_unknown_keys(cls: type, d: Mapping[str, Any], where: str, error: type[Exception] = ValueError) -> None:
    """Raise ``error`` naming every key of ``d`` that is not a field of dataclass ``cls``."""
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(d) - known)
    if unknown:
        raise error(f"{where}: unknown keys {unknown}; allowed: {sorted(known)}")


def from_dict(cls: type, d: Mapping[str, Any] | None, where: str, error: type[Exception] = ValueError,
              check_types: bool = False):
    """Build dataclass ``cls`` from a config mapping; unknown keys raise ``error`` naming them.

    A ``cls`` instance is returned as it is. Fields typed with a dataclass (nested sections) are
    parsed from their mapping: unknown keys fail naming ``where.field``, then the nested class's own
    ``from_dict`` (when it has one) checks the values.

    ``check_types``: also check each value against the type of the field's default (bool, int,
    float, fixed-length tuple; ints are accepted for floats) and raise ValueError naming the key."""
    if isinstance(d, cls):
        return d
    if d is not None and not isinstance(d, Mapping):
        raise error(f"{where}: expected a mapping, got {type(d).__name__}")
    d = dict(d or {})
    reject_unknown_keys(cls, d, where, error)
    for key, sub in nested_sections(cls).items():
        if key in d and not isinstance(d[key], sub):
            d[key] = _nested(sub, d[key], f"{where}.{key}", error)
    if check_types:
        defaults = cls()
        for key, value in list(d.items()):
            d[key] = _typed(getattr(defaults, key), value, f"{where}.{key}")
    return cls(**d)


class Section:
    """Mixin of every config-section dataclass, the one config mechanism: ``from_dict`` builds the section from
    a mapping (a key in ``RENAMED`` raises naming its new key, an unknown key raises ``ERROR`` naming ``WHERE``
    and the allowed keys, a nested section is parsed by its own class), and every construction, from a mapping
    or in code, runs ``validate``. ``CHECK_TYPES``: values are also checked against their defaults' types."""

    WHERE: ClassVar[str] = "config"
    ERROR: ClassVar[type[Exception]] = ValueError
    CHECK_TYPES: ClassVar[bool] = False
    #: an old key of this section -> where it is set now (a path from the config's root, or a phrase)
    RENAMED: ClassVar[Mapping[str, str]] = {}
    #: fields the workflow hands in from one setting read once (``seed``, ``device``, ``fps``: the workflow config's
    #: top level; ``background``: the scene file's; :data:`anigs.config.HANDED`): library arguments, not keys of
    #: this section in a config file (the schema leaves them out, and a config file that sets one fails naming it)
    HANDED: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        self.validate()

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None):
        if isinstance(d, cls):
            return d
        old = [k for k in (d if isinstance(d, Mapping) else ()) if k in cls.RENAMED]
        if old:
            raise cls.ERROR(f"{cls.WHERE}: " + "; ".join(f"{k} is now {cls.RENAMED[k]}" for k in old))
        return from_dict(cls, d, cls.WHERE, cls.ERROR, cls.CHECK_TYPES)

    def validate(self) -> None:
        """Check the values (raise ``ValueError`` naming the key); may normalise them (lists to tuples)."""


def nested_sections(cls: type) -> dict[str, type]:
    """Field name -> dataclass type, for the fields of dataclass ``cls`` that are nested sections."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if dataclasses.is_dataclass(hints[f.name])}


def _nested(sub: type, value: Any, where: str, error: type[Exception]):
    """Nested section ``sub`` from its mapping: unknown keys named with their path, then checked by
    ``sub.from_dict`` where it has one (its own validation), else built here."""
    if value is not None and not isinstance(value, Mapping):
        raise error(f"{where}: expected a mapping, got {type(value).__name__}")
    if issubclass(sub, Section):
        return sub.from_dict(value)
    reject_unknown_keys(sub, value or {}, where, error)
    return from_dict(sub, value, where, error)


def _typed(ref: Any, value: Any, where: str) -> Any:
    """``value`` checked against (and coerced to) the type of the default ``ref``."""
    if isinstance(ref, bool):
        ok = isinstance(value, bool)
    elif isinstance(ref, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(ref, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        value = float(value) if ok else value
    elif isinstance(ref, tuple):
        ok = isinstance(value, (list, tuple)) and len(value) == len(ref)
        value = tuple(float(v) for v in value) if ok else value
    else:
        ok = True
    if not ok:
        raise ValueError(f"{where}: expected {type(ref).__name__} like {ref!r}, got {value!r}")
    return value


def check_in(name: str, value: float, lo: float, hi: float) -> None:
    """A ``ValueError`` naming the setting (``capture.fov_deg must be in [20, 120], got 10``) when
    ``value`` lies outside ``[lo, hi]``."""
    if not lo <= value <= hi:
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {value}")
