"""Reading alight's YAML files (scenarios, campaigns, airframes, device profiles, QoS measurements): one
loader, so every file refuses a key given twice and reports bad YAML the same way, in one line."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from alight.errors import ConfigError


class UniqueKeyLoader(yaml.SafeLoader):  # type: ignore[misc,unused-ignore]  # PyYAML has no stubs here
    """PyYAML's safe loader, refusing a key given twice in one mapping (the plain loader keeps the last
    one silently, so ``speed_mps: 2`` ... ``speed_mps: 20`` would fly the second)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key: the base class reports it
                break
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} given twice", key_node.start_mark
                )
            seen.add(key)
        mapping: dict[Any, Any] = super().construct_mapping(node, deep=deep)
        return mapping


def load_yaml_text(text: str, source: str, what: str = "scenario", *, allow_empty: bool = False) -> Any:
    """Parse YAML with :class:`UniqueKeyLoader`; bad YAML or a duplicate key becomes one ``ConfigError``
    line naming ``source`` (and the line where YAML says it), and so does an empty document unless
    ``allow_empty`` (then it is None, for a caller whose own validation says what is missing)."""
    try:
        data = yaml.load(text, Loader=UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)  # third-party: only marked PyYAML errors have one
        line = getattr(mark, "line", None)  # third-party: a PyYAML mark
        where = f" (line {line + 1})" if line is not None else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]  # third-party: a PyYAML error
        raise ConfigError(f"{source}: not valid YAML{where}: {problem}") from None
    except RecursionError:
        raise ConfigError(f"{source}: not valid YAML: nested too deeply") from None
    if data is None and not allow_empty:
        raise ConfigError(f"{source}: the file is empty (write {{}} for a {what} with every default)")
    return data


def read_yaml_file(
    path: str | Path, what: str, *, source: str | None = None, allow_empty: bool = False
) -> tuple[Any, str]:
    """The parsed document and the text of the ``what`` file (``scenario``, ``campaign``...) at ``path``:
    a missing, unreadable or non-UTF-8 file and bad YAML become one ``ConfigError`` line naming ``source``
    (default: the path); see :func:`load_yaml_text`."""
    p = Path(path)
    where = str(p) if source is None else source
    if not p.is_file():
        raise ConfigError(f"{where}: no such {what} file")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise ConfigError(f"{where}: not valid YAML: not UTF-8 text ({err.reason})") from None
    except OSError as err:
        raise ConfigError(f"{where}: cannot read the {what} file: {err.strerror or err}") from None
    return load_yaml_text(text, where, what, allow_empty=allow_empty), text


def unwrap_quantities(data: Any, units: Mapping[str, str]) -> Any:
    """A data file's ``key: {value: V, unit: U, source: S}`` -> ``key: V`` once ``U`` is ``units[key]``
    (the airframe and vessel files give each physical value with its unit and its source); a value given
    plainly stays as it is. A wrong unit or an unknown sub-key is a ``ValueError`` (pydantic's
    validators turn it into a one-line refusal)."""
    if not isinstance(data, dict):
        return data
    out = dict(data)
    for key, item in data.items():
        if key not in units or not isinstance(item, dict):
            continue
        unknown = sorted(set(item) - {"value", "unit", "source"})
        if unknown:
            raise ValueError(f"{key}: unknown key(s) {unknown}, expected value, unit, source")
        if "value" not in item:
            raise ValueError(f"{key}: a mapping needs 'value'")
        unit = item.get("unit", units[key])
        if str(unit) != units[key]:
            raise ValueError(f"{key}: unit must be '{units[key]}', got '{unit}'")
        out[key] = item["value"]
    return out


def data_file_error(source: str, err: ValidationError) -> str:
    """One line for a data file (airframe, vessel) that pydantic refused: the first error's key, message
    and value, and how many more there are."""
    first = err.errors()[0]
    where = ".".join(str(p) for p in first["loc"])
    msg = first["msg"].removeprefix("Value error, ")
    got = first.get("input")
    shown = "" if isinstance(got, dict | list) or got is None or not where else f", got {got!r}"
    extra = f" (and {err.error_count() - 1} more)" if err.error_count() > 1 else ""
    return f"{source}: {where + ': ' if where else ''}{msg}{shown}{extra}"


__all__ = ["UniqueKeyLoader", "data_file_error", "load_yaml_text", "read_yaml_file", "unwrap_quantities"]
