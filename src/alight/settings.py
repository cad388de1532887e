"""Settings: the runtime configuration dataclasses are the schema of the scenario files.

Each setting is declared once, as a field of the dataclass that uses it (``MissionConfig``,
``TouchdownConfig``, ``TelemetryConfig``, ...): its type, its default, its bound (``Annotated[float,
Field(gt=0)]``) and its docstring. The dataclasses are pydantic dataclasses (:data:`SETTINGS`), so building
one validates it, with the same one-line messages a scenario file gets. A scenario section is either the
dataclass itself (``platform.telemetry``) or a model derived from its fields by :func:`section_model`:

- ``optional=True``: every field Optional with default None, "None means the preset's or the block's
  value" (``mission``, ``mission.touchdown``);
- ``optional=False``: the dataclass's own defaults, for a sensor whose other fields the simulator sets
  (``rangefinder``: its position comes from the airframe).

Each derived model records where its keys come from (:func:`sources`); ``tests/meta/test_single_source.py``
lists every scenario key with its one declaration.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Any, cast, get_args, get_origin

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)
from pydantic.dataclasses import is_pydantic_dataclass
from pydantic.fields import FieldInfo

SETTINGS = ConfigDict(extra="forbid", use_attribute_docstrings=True)
"""The pydantic configuration of every settings dataclass: unknown keys are errors, the attribute
docstrings are the fields' descriptions (the generated docs read them)."""

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Probability = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]

MIN_RATE_HZ = 0.1
"""Slowest sensor, loop or frame rate (Hz): a reading less often than every 10 s is no feedback for a
vehicle that moves metres per second (1e-9 Hz flew as a mission without a single reading)."""
RateHz = Annotated[float, Field(ge=MIN_RATE_HZ, le=1000.0, allow_inf_nan=False)]
"""A sensor, loop or frame rate (Hz), from :data:`MIN_RATE_HZ` to 1000."""

MAX_DURATION_S = 3600.0
"""Longest mission (s): an hour, ten times a multirotor's endurance."""
Altitude = Annotated[float, Field(gt=0, le=1000.0, allow_inf_nan=False)]
"""An altitude or a height (m), at most 1000."""
Duration = Annotated[float, Field(gt=0, le=MAX_DURATION_S, allow_inf_nan=False)]
"""A time span within one mission (s), at most :data:`MAX_DURATION_S`."""


def _is_int_field(annotation: Any) -> bool:
    """Whether a field's type is ``int`` or ``int | None`` (bool aside: a bool field takes booleans)."""
    candidates = (annotation, *get_args(annotation))
    members = [get_args(a)[0] if get_origin(a) is Annotated else a for a in candidates]
    return int in members and bool not in members


def refuse_bool_for_int(model: type[BaseModel], name: str, value: Any) -> Any:
    """``value`` unchanged, unless field ``name`` of ``model`` is an integer and ``value`` a boolean:
    pydantic's lax mode reads ``seed: true`` as seed 1, a typo flown as a result."""
    field = model.model_fields.get(name)
    if isinstance(value, bool) and field is not None and _is_int_field(field.annotation):
        raise ValueError(f"an integer, not a boolean ({str(value).lower()})")
    return value


class Section(BaseModel):
    """Base of the derived scenario sections: frozen, unknown keys refused, no boolean for an integer.
    For the type checker a derived section is this class with any attribute (mypy cannot see fields made
    at import time)."""

    model_config = ConfigDict(extra="forbid", frozen=True, use_attribute_docstrings=True)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_int(cls, value: Any, info: ValidationInfo) -> Any:
        return refuse_bool_for_int(cls, str(info.field_name), value)

    if TYPE_CHECKING:

        def __getattr__(self, name: str) -> Any: ...


SourceMap = Mapping[str, tuple[type, str]]
"""Scenario key -> (the dataclass, its field) that declares it."""

_SOURCES: dict[type, SourceMap] = {}


def sources(model: type) -> SourceMap:
    """Where the keys of a derived section come from (empty for a model written by hand)."""
    return _SOURCES.get(model, {})


def field_info(cls: type, name: str) -> FieldInfo:
    """The pydantic field of settings dataclass ``cls`` named ``name`` (its type, bound, default, doc)."""
    fields: dict[str, FieldInfo] = cls.__pydantic_fields__  # type: ignore[attr-defined]
    return fields[name]


def section_fields(cls: type) -> dict[str, FieldInfo]:
    """The fields of a scenario section: a pydantic model's, or a settings dataclass's."""
    if isinstance(cls, type) and issubclass(cls, BaseModel):
        return dict(cls.model_fields)
    return dict(cls.__pydantic_fields__)  # type: ignore[attr-defined]


def is_section(annotation: Any) -> type | None:
    """The section type in a field's annotation (a pydantic model or a settings dataclass), if any."""
    for a in get_args(annotation) or (annotation,):
        if isinstance(a, type) and (issubclass(a, BaseModel) or is_pydantic_dataclass(a)):
            return a
    return None


def default_of(cls: type, name: str) -> Any:
    """The default of field ``name`` of settings dataclass ``cls``."""
    return field_info(cls, name).get_default(call_default_factory=True)


def _derived_field(info: FieldInfo, optional: bool) -> tuple[Any, Any]:
    annotation: Any = info.annotation
    if info.metadata:
        annotation = Annotated[(annotation, *info.metadata)]
    if optional:
        return annotation | None, Field(default=None, description=info.description)
    if info.default_factory is not None:
        factory: Callable[[], Any] = info.default_factory  # type: ignore[assignment]
        return annotation, Field(default_factory=factory, description=info.description)
    return annotation, Field(default=info.default, description=info.description)


def _checked_by(cls: type, keys: Mapping[str, str]) -> Callable[[Any], Any]:
    """An after-validator that builds ``cls`` from the section's set values, so that the dataclass's own
    cross-field checks (``__post_init__``) are the section's: declared once."""

    def check(self: Any) -> Any:
        given = {field: getattr(self, key) for key, field in keys.items() if getattr(self, key) is not None}
        try:
            cls(**given)
        except ValidationError as err:
            first = err.errors()[0]
            where = ".".join(str(p) for p in first["loc"])
            msg = str(first["msg"]).removeprefix("Value error, ")
            raise ValueError(f"{where}: {msg}" if where else msg) from None
        return self

    return check


def section_model(
    name: str,
    doc: str,
    parts: Sequence[tuple[type, Sequence[str] | Mapping[str, str]]],
    *,
    optional: bool,
    keep_defaults: Sequence[str] = (),
    extra: Mapping[str, tuple[Any, Any]] | None = None,
    check: type | None = None,
    base: type[BaseModel] = Section,
) -> type[Section]:
    """A scenario section derived from settings dataclasses: for each ``(cls, keys)`` of ``parts`` the
    fields ``keys`` of ``cls`` (a mapping renames: scenario key -> field), with their types, bounds and
    docstrings; defaults None when ``optional`` (but for ``keep_defaults``, which keep the dataclass's),
    else the dataclass's. ``extra`` adds keys of the scenario's own (``name: (annotation, default)``);
    ``check`` names a dataclass built from the set values to run its cross-field checks."""
    fields: dict[str, Any] = {}
    origin: dict[str, tuple[type, str]] = {}
    for cls, keys in parts:
        renames = dict(keys) if isinstance(keys, Mapping) else {k: k for k in keys}
        for key, field in renames.items():
            if key in fields:
                raise ValueError(
                    f"{name}.{key} is declared twice ({origin[key][0].__name__}, {cls.__name__})"
                )
            fields[key] = _derived_field(field_info(cls, field), optional and key not in keep_defaults)
            origin[key] = (cls, field)
    fields.update(extra or {})
    validators: dict[str, Any] = {}
    if check is not None:
        keys = {k: f for k, (c, f) in origin.items() if c is check}
        validators["_checked"] = model_validator(mode="after")(_checked_by(check, keys))
    module = sys._getframe(1).f_globals["__name__"]  # the defining module, for pickling and the docs
    model = create_model(
        name, __base__=base, __doc__=doc, __module__=module, __validators__=validators, **fields
    )
    _SOURCES[model] = origin
    return cast(type[Section], model)


def dataclass_keys(cls: type) -> tuple[str, ...]:
    """The field names of a dataclass, in declaration order."""
    return tuple(f.name for f in dataclasses.fields(cls))
