"""What a block is, as the stages' registries declare it: :class:`BlockSpec`.

Each stage owns one table ``name -> BlockSpec`` (``alight.cameras.CAMERAS``, ``alight.pads.PADS``,
``alight.perception.DETECTORS`` and ``GEOLOCATORS``, ``alight.estimation.PLATFORM_ESTIMATORS``,
``alight.control.CONTROLLERS``, ``alight.planning.PLANNERS``); the flight, ``alight blocks``, ``alight
detect``, the docs generator and the contract tests read those tables, and
:func:`alight.mission.blocks.register_block` adds to them. A spec carries, as data:

- ``params``: a frozen dataclass whose fields are the block's parameters with their defaults (the
  algorithm's own config class where it has one), plus ``defaults``: the values missions fly where they
  differ from the class's library defaults;
- ``context`` / ``context_values``: parameters filled from the scenario (or an upstream block) when not
  given: a line saying where from (for the docs) and the function that reads them off a
  :class:`ResolveContext`;
- ``needs`` / ``provides``: what the block requires of the other stages' choices and what it offers;
- ``build``: the factory ``(params, context) -> the object that flies``, with the stage's typed build
  context (a camera model and mount, the pad, the airframe, ...).

This module is a leaf below every stage: it knows no algorithm.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import textwrap
from collections.abc import Callable, Mapping
from dataclasses import KW_ONLY, dataclass, field
from functools import cache
from typing import Any, Generic, TypeVar

C = TypeVar("C")
"""The stage's build context."""
T = TypeVar("T")
"""What the stage's blocks build."""


@dataclass(frozen=True)
class NoContext:
    """The build context of a stage whose blocks need nothing but their parameters (the pads)."""


@dataclass(frozen=True, kw_only=True)
class ResolveContext:
    """What a block may take its unset parameters from, when a scenario's blocks are resolved."""

    pad_size_m: float = 1.5
    """The scenario's ``platform.pad_size_m``."""
    pad_height_m: float = 0.0
    """The scenario's ``platform.pad_height_m`` (the deck's height in W, m)."""
    mitigation: str = "none"
    """The scenario's ``perception.mitigation``."""
    calibration: str | None = None
    """The scenario's ``camera.calibration``."""
    upstream: Mapping[str, BlockSpec[Any, Any]] = field(default_factory=dict)
    """The blocks chosen for the stages before this one (data-flow order), by stage."""


def _no_values(_: ResolveContext) -> Mapping[str, Any]:
    return {}


@dataclass(frozen=True)
class BlockSpec(Generic[C, T]):
    """One block as its stage's registry declares it (module docstring)."""

    stage: str
    name: str
    summary: str
    params: type
    """Frozen dataclass of the parameters; its field defaults are the library defaults."""
    _: KW_ONLY
    build: Callable[[Any, C], T]
    """The factory: an instance of ``params`` and the stage's build context -> the block's object."""
    defaults: Mapping[str, Any] = field(default_factory=dict)
    """Defaults that missions fly where they differ from ``params``' own (the block's defaults)."""
    context: Mapping[str, str] = field(default_factory=dict)
    """Parameter -> where its value comes from when not given (a scenario key or another block)."""
    context_values: Callable[[ResolveContext], Mapping[str, Any]] = _no_values
    """The values of the ``context`` parameters for a scenario."""
    needs: Mapping[str, tuple[Any, ...]] = field(default_factory=dict)
    """``"<stage>"`` -> the block names it works with, or ``"<stage>.<feature>"`` -> the values of that
    feature (in the chosen block's ``provides``) it accepts."""
    provides: Mapping[str, Any] = field(default_factory=dict)
    hidden: tuple[str, ...] = ()
    """Fields of ``params`` that are not block parameters (objects the builder passes)."""

    def parameters(self) -> list[tuple[str, Any, str]]:
        """(name, default, docstring) of every parameter, the block's defaults applied."""
        docs = field_docs(self.params)
        out = []
        for f in dataclasses.fields(self.params):
            if f.name in self.hidden or not f.init:
                continue
            if f.name in self.defaults:
                default: Any = self.defaults[f.name]
            elif f.default is not dataclasses.MISSING:
                default = f.default
            elif f.default_factory is not dataclasses.MISSING:
                default = f.default_factory()
            else:
                default = None
            out.append((f.name, default, docs.get(f.name, "")))
        return out

    def make_params(self, given: Mapping[str, Any], context: Mapping[str, Any], where: str) -> Any:
        """The block's parameter dataclass from its defaults, the scenario's ``context`` values and
        ``given``; a ``ValueError`` naming ``where`` for an unknown or rejected parameter."""
        known = {f.name: f for f in dataclasses.fields(self.params) if f.init and f.name not in self.hidden}
        for key in given:
            if key not in known:
                raise ValueError(
                    f"{where}.{key}: unknown parameter of {self.stage} '{self.name}' "
                    f"(known: {', '.join(known)})"
                )
        defaults = {name: d for name, d, _ in self.parameters()}
        kw: dict[str, Any] = {k: v for k, v in self.defaults.items() if k in known}
        for k, v in context.items():
            if k in known and kw.get(k) is None:
                kw[k] = v
        for key, value in given.items():
            kw[key] = _given_value(known[key], defaults.get(key), value, f"{where}.{key}")
        kw = {k: v for k, v in kw.items() if not (v is None and k in self.defaults and k not in given)}
        try:
            return self.params(**kw)
        except (ValueError, TypeError) as err:
            raise ValueError(f"{where}: {self.stage} '{self.name}' rejects its parameters: {err}") from None

    def default_params(self, context: ResolveContext | None = None) -> Any:
        """The parameters the block flies with when a scenario sets none (``context``: the scenario's
        values; None: :class:`ResolveContext`'s defaults)."""
        ctx = ResolveContext() if context is None else context
        return self.make_params({}, self.context_values(ctx), f"{self.stage} '{self.name}'")

    def build_default(self, context: C, values: ResolveContext | None = None) -> T:
        """The block's object at :meth:`default_params` (a test's or a tool's, outside a scenario)."""
        return self.build(self.default_params(values), context)


def _given_value(f: dataclasses.Field[Any], default: Any, value: Any, where: str) -> Any:
    """A parameter's given value, checked against its default's kind; a mapping for a dataclass-valued
    parameter sets fields of its default."""
    sub = f.type if isinstance(f.type, type) else None
    if dataclasses.is_dataclass(default) and isinstance(value, Mapping):
        try:
            return dataclasses.replace(default, **value)  # type: ignore[type-var]
        except (TypeError, ValueError) as err:
            raise ValueError(f"{where}: {err}") from None
    if sub is not None and dataclasses.is_dataclass(sub) and isinstance(value, Mapping):
        return sub(**value)
    _check_type(value, default, where)
    return value


def _check_type(value: Any, default: Any, where: str) -> None:
    """Reject a value of the wrong kind for a scalar parameter (a YAML typo: a string for a number)."""
    if default is None or value is None:
        return
    if isinstance(default, bool):
        ok = isinstance(value, bool)
        kind = "true or false"
    elif isinstance(default, int | float) and not isinstance(default, bool):
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if ok and isinstance(default, int) and not isinstance(value, int) and float(value).is_integer():
            ok = True
        kind = "a number"
        if ok and not math.isfinite(float(value)):
            raise ValueError(f"{where}: must be finite, got {value!r}")
    elif isinstance(default, str):
        ok, kind = isinstance(value, str), "a string"
    else:
        return
    if not ok:
        raise ValueError(f"{where}: expected {kind}, got {value!r}")


@cache  # reading and parsing the source costs ~50 ms a class; the scenario validation asks often
def field_docs(cls: type) -> dict[str, str]:
    """The docstrings under a dataclass's fields (the attribute-docstring convention of this codebase)."""
    try:
        src = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    tree = ast.parse(src)
    out: dict[str, str] = {}
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    for a, b in zip(body, body[1:], strict=False):
        if (
            isinstance(a, ast.AnnAssign)
            and isinstance(a.target, ast.Name)
            and isinstance(b, ast.Expr)
            and isinstance(b.value, ast.Constant)
            and isinstance(b.value.value, str)
        ):
            out[a.target.id] = " ".join(b.value.value.split())
    return out


def signature_params(cls: type, skip: tuple[str, ...], doc: str) -> type:
    """A frozen dataclass of a constructor's keyword parameters (after ``skip``), with its defaults: the
    block's parameters are its constructor's, listed once."""
    fields_: list[tuple[str, Any, Any]] = []
    for p in inspect.signature(cls).parameters.values():
        if p.name in skip or p.name == "self" or p.default is inspect.Parameter.empty:
            continue
        fields_.append((p.name, Any, field(default=p.default)))
    made = dataclasses.make_dataclass(f"{cls.__name__}Params", fields_, frozen=True, kw_only=True)
    made.__doc__ = doc
    return made


def param_kwargs(params: Any) -> dict[str, Any]:
    """A parameter dataclass's fields as keyword arguments (for a constructor that takes them so)."""
    return {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}


__all__ = [
    "BlockSpec",
    "NoContext",
    "ResolveContext",
    "field_docs",
    "param_kwargs",
    "signature_params",
]
