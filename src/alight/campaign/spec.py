"""Campaign files: many missions over conditions, presets and seeds, validated with pydantic.

A campaign names a base scenario, the presets to compare, how many seeds each condition is flown with,
and the conditions: a ``grid`` (cartesian product), an explicit list of ``conditions``, and/or
conditions drawn at random (``sample``). Parameters are named by their dotted scenario path
(``platform.speed_mps``). ``load_campaign`` expands the file into its missions and validates every
mission's scenario at once, so a bad value fails before anything flies, with one ``ConfigError`` line
that names the condition.

Expansion order (it fixes the condition ids ``c000``, ``c001``, ... and through them the seeds):

1. the grid's product, the last key varying fastest (``itertools.product``);
2. then the explicit ``conditions`` in file order;
3. if ``sample`` is given, each of those conditions (or the base alone, when there are none) is
   repeated ``sample.n`` times with freshly drawn sampled parameters.

Missions are ordered condition by condition, replicate by replicate, preset by preset, so a campaign
stopped early holds paired results of every preset.

Size: the number of missions (conditions x ``seeds_per_condition`` x presets, the conditions being the
grid's product plus the explicit ones, times ``sample.n``) is counted from the file before anything is
expanded, and a campaign of more than :data:`MAX_MISSIONS` is refused with one line. Each planned mission
holds its whole scenario (10-25 kB, 0.3 ms to expand), so the cap keeps the expansion under a minute and a
few GB; a bigger study is several campaigns. With ``limit`` (``alight campaign --limit N``) only the
conditions of the first ``N`` missions are expanded, grid points and sampled draws alike (a ``sample.n``
of a billion with ``--limit 1`` draws one condition), and the cap applies to those.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, model_validator

from alight.campaign.seeds import mission_seed, sample_rng
from alight.errors import ConfigError
from alight.scenario import Scenario, load_scenario, read_yaml_file, scenario_from_dict

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]

MAX_MISSIONS = 100_000
"""Largest number of missions one campaign file may expand to (see "Size" in the module docstring)."""
VIEWS_PER_CELL = 3
"""Default of a campaign's ``views_per_cell``: the views of a failure cost more than its flight (about
4 s against 3 s for a 30 s falanga2017 mission, issue 18), and a few per cell show what went wrong."""

_RESERVED = {
    "preset": "choose presets with the campaign's 'presets' list",
    "seed": "scenario seeds come from the campaign's 'seed' and 'seeds_per_condition'",
}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Uniform(_Strict):
    """Uniform on [low, high)."""

    dist: Literal["uniform"]
    low: FiniteFloat
    high: FiniteFloat

    @model_validator(mode="after")
    def _ordered(self) -> Uniform:
        if not self.high > self.low:
            raise ValueError("needs high > low")
        return self


class LogUniform(_Strict):
    """Log-uniform on [low, high): uniform in log(value); for scales such as noise levels."""

    dist: Literal["loguniform"]
    low: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    high: Annotated[float, Field(gt=0, allow_inf_nan=False)]

    @model_validator(mode="after")
    def _ordered(self) -> LogUniform:
        if not self.high > self.low:
            raise ValueError("needs high > low")
        return self


class Normal(_Strict):
    """Normal with mean and standard deviation (unbounded: a draw outside the scenario's range fails
    validation at load time, naming the condition)."""

    dist: Literal["normal"]
    mean: FiniteFloat
    std: PositiveFloat


class Choice(_Strict):
    """One of ``values``, with probabilities ``p`` (uniform when absent)."""

    dist: Literal["choice"]
    values: Annotated[list[Any], Field(min_length=1)]
    p: list[Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]] | None = None

    @model_validator(mode="after")
    def _weights(self) -> Choice:
        if self.p is not None:
            if len(self.p) != len(self.values):
                raise ValueError("p needs one probability per value")
            if not math.isclose(sum(self.p), 1.0, abs_tol=1e-9):
                raise ValueError(f"p must sum to 1, sums to {sum(self.p)}")
        return self


Distribution = Annotated[Uniform | LogUniform | Normal | Choice, Field(discriminator="dist")]
_DISTRIBUTION = TypeAdapter(Distribution)


def _draw(dist: Uniform | LogUniform | Normal | Choice, rng: Any) -> Any:
    if isinstance(dist, Uniform):
        return float(rng.uniform(dist.low, dist.high))
    if isinstance(dist, LogUniform):
        return float(math.exp(rng.uniform(math.log(dist.low), math.log(dist.high))))
    if isinstance(dist, Normal):
        return float(rng.normal(dist.mean, dist.std))
    index = int(rng.choice(len(dist.values), p=dist.p))
    return copy.deepcopy(dist.values[index])


class BlockSet(_Strict):
    """A named set of blocks, flown and reported like a preset: the ``name`` labels its missions (the
    ``preset`` column of results.csv, the groups of the report)."""

    name: Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9._+-]*$", max_length=60)]
    preset: str | None = None
    """The preset it starts from; default: the base scenario's."""
    blocks: dict[str, Any] = Field(default_factory=dict)
    """The scenario's ``blocks:`` entries (stage -> name or ``{name: ..., <parameters>}``)."""


class CampaignSpec(_Strict):
    """The campaign file as written."""

    name: Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]*$", max_length=100)]
    """Names the campaign and its default output directory ``runs/<name>``."""
    description: str | None = None
    base: dict[str, Any] | str = Field(default_factory=dict)
    """The base scenario: a mapping of scenario keys, or a scenario file relative to the campaign file."""
    presets: Annotated[list[str | BlockSet], Field(min_length=1)] | None = None
    """Presets to compare, each a preset name or a named block set (``{name, preset, blocks}``), compared
    in the reports as presets are; default: the base scenario's preset."""
    seeds_per_condition: Annotated[int, Field(ge=1)] = 1
    seed: Annotated[int, Field(ge=0)] = 0
    """Root of the SeedSequence tree every scenario seed and every sampled value comes from."""
    grid: dict[str, Annotated[list[Any], Field(min_length=1)]] = Field(default_factory=dict)
    """Dotted scenario path -> values; the conditions are the cartesian product."""
    conditions: list[dict[str, Any]] = Field(default_factory=list)
    """Explicit conditions (dotted path -> value), appended after the grid's."""
    sample: dict[str, Any] | None = None
    """``n`` (draws per condition) and dotted path -> distribution."""
    same_seeds_across: list[str] = Field(default_factory=list)
    """Dotted paths whose values do not change the seeds: conditions that differ only in these share
    their missions' seeds, for a paired comparison of settings (as presets always are), e.g. a
    controller option or a quality-of-service policy flown on the same platforms, winds and noise."""
    duration_s: PositiveFloat | None = None
    """Overrides the base scenario's simulated duration (s)."""
    timeout_s: PositiveFloat = 600.0
    """Wall-clock limit of one mission (s); a mission still running then is killed, recorded as an error."""
    views_per_cell: Annotated[int, Field(ge=0)] | Literal["all"] = VIEWS_PER_CELL
    """How many failures of each (preset, condition) cell get their views (figures, report.html and
    replay.gif): the first ones by replicate, flown again after the sweep. ``all``: every failure, drawn
    from its one flight during the sweep. Every failure keeps its log, scenario and result either way."""


@dataclass(frozen=True)
class Condition:
    index: int
    condition_id: str
    params: dict[str, Any]
    """Every swept or sampled parameter (dotted path -> value), the base's value where not set."""


@dataclass(frozen=True)
class PlannedMission:
    mission_id: str
    condition_id: str
    condition_index: int
    preset: str
    replicate: int
    seed: int
    params: dict[str, Any]
    scenario: dict[str, Any]
    """The mission's whole scenario as JSON-compatible data (``Scenario.model_validate`` takes it)."""


@dataclass(frozen=True)
class Campaign:
    """A campaign file expanded into its missions."""

    spec: CampaignSpec
    conditions: list[Condition]
    missions: list[PlannedMission]
    swept_parameters: list[str]
    presets: list[str]
    source: Path | None = None
    text: str | None = field(default=None, repr=False)
    """The campaign file's text as read (copied into the output directory)."""

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def timeout_s(self) -> float:
        return self.spec.timeout_s


def mission_id(condition_id: str, preset: str, replicate: int) -> str:
    return f"{condition_id}-{preset}-r{replicate:03d}"


def _format_validation(prefix: str, err: ValidationError) -> str:
    first = err.errors()[0]
    where = ".".join(str(p) for p in first["loc"])
    msg = first["msg"]
    extra = f" (and {err.error_count() - 1} more)" if err.error_count() > 1 else ""
    got = first.get("input")
    shown = "" if isinstance(got, dict | list) or got is None else f", got {got!r}"
    if not where and first["type"] == "value_error":
        msg = msg.removeprefix("Value error, ")  # a whole-scenario check (the blocks) names its key
    where = f"{where}: " if where else ""
    return f"{prefix}: {where}{msg}{shown}{extra}"


def _get(tree: Mapping[str, Any], path: str) -> Any:
    node: Any = tree
    for part in path.split("."):
        node = node[part]
    return node


def _check_path(tree: Mapping[str, Any], path: str, where: str) -> None:
    if not isinstance(path, str) or not path:
        raise ConfigError(f"{where}: a parameter must be a dotted scenario path, got {path!r}")
    parts = path.split(".")
    if parts[0] in _RESERVED:
        raise ConfigError(f"{where}: '{path}' cannot be swept ({_RESERVED[parts[0]]})")
    node: Any = tree
    for i, part in enumerate(parts):
        if not isinstance(node, dict) or part not in node:
            parent = ".".join(parts[:i]) or "the scenario"
            known = ", ".join(sorted(node)) if isinstance(node, dict) else "no keys"
            raise ConfigError(f"{where}: '{path}' is not a scenario key ('{part}' not in {parent}: {known})")
        node = node[part]


def _set(tree: dict[str, Any], path: str, value: Any) -> None:
    parts = path.split(".")
    node = tree
    for part in parts[:-1]:
        node = node[part]
    node[parts[-1]] = copy.deepcopy(value)


def _grouped(tree: Mapping[str, Any], preset: str, blocks: Mapping[str, Any]) -> dict[str, Any]:
    """The mission's scenario for a group: its preset, and a block set's entries over the blocks."""
    out = copy.deepcopy(dict(tree))
    out["preset"] = preset
    if blocks:
        out["blocks"] = {**(out.get("blocks") or {}), **copy.deepcopy(dict(blocks))}
    return out


def _short(params: Mapping[str, Any], limit: int = 120) -> str:
    text = ", ".join(f"{k}={json.dumps(v)}" for k, v in params.items())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _base_scenario(spec: CampaignSpec, source: str, base_dir: Path) -> Scenario:
    if isinstance(spec.base, str):
        path = Path(spec.base)
        if not path.is_absolute():
            path = base_dir / path
        return load_scenario(path)
    return scenario_from_dict(spec.base, f"{source}: base")


def count_missions(spec: CampaignSpec) -> int:
    """How many missions ``spec`` expands to, from the sizes alone (nothing is expanded): the grid's
    product plus the explicit conditions (at least one condition), times ``sample.n``, times
    ``seeds_per_condition``, times the presets. Exact for a valid spec (``expand_campaign`` refuses a
    repeated condition rather than dropping it)."""
    n_conditions = (math.prod(len(v) for v in spec.grid.values()) if spec.grid else 0) + len(spec.conditions)
    n_conditions = max(n_conditions, 1)
    if spec.sample is not None:
        n = spec.sample.get("n")
        if isinstance(n, int) and not isinstance(n, bool) and n >= 1:
            n_conditions *= n
    n_presets = len(spec.presets) if spec.presets is not None else 1
    return n_conditions * spec.seeds_per_condition * n_presets


_Groups = dict[str, tuple[str, dict[str, Any]]]
"""A campaign's groups: label -> (preset, block overrides); a preset stands for itself, a block set
for its blocks over its preset."""
_Dist = Uniform | LogUniform | Normal | Choice


def expand_campaign(
    spec: CampaignSpec, *, source: str = "campaign", base_dir: Path | None = None, limit: int | None = None
) -> tuple[list[Condition], list[PlannedMission], list[str], list[str]]:
    """Conditions, missions, swept parameter paths and presets of ``spec``; raises ``ConfigError``.

    ``limit``: expand only the conditions of the first ``limit`` missions (and return those missions):
    grid points and sampled draws alike are made lazily, so a limit on a huge campaign costs only its
    head. More than :data:`MAX_MISSIONS` missions (after ``limit``) is a ``ConfigError``."""
    wanted = _wanted_missions(spec, source, limit)
    base = _base_scenario(spec, source, base_dir or Path.cwd())
    if spec.duration_s is not None:
        base = base.model_copy(update={"duration_s": spec.duration_s})
    base_tree = base.model_dump(mode="json")
    groups = _preset_groups(spec, base.preset, source)
    presets = list(groups)
    paths, dists, n_draws = _swept_parameters(spec, base_tree, source)
    n_conditions = -(-wanted // (spec.seeds_per_condition * len(presets)))
    raw_conditions = _raw_conditions(spec, dists, n_draws, n_conditions, source)
    conditions, trees = _validated_conditions(raw_conditions, base_tree, groups, paths, source)
    unknown = sorted(set(spec.same_seeds_across) - set(paths))
    if unknown:
        raise ConfigError(f"{source}: same_seeds_across names {unknown}, which the campaign does not sweep")
    missions = _planned_missions(spec, conditions, trees, groups, paths, wanted)
    return conditions, missions, paths, presets


def _wanted_missions(spec: CampaignSpec, source: str, limit: int | None) -> int:
    """How many missions to expand: all, or the first ``limit``; over :data:`MAX_MISSIONS` is refused
    from the count alone, before anything is expanded."""
    if limit is not None and limit < 1:
        raise ConfigError(f"{source}: the mission limit must be >= 1, got {limit}")
    total = count_missions(spec)
    wanted = total if limit is None else min(total, limit)
    if wanted > MAX_MISSIONS:
        raise ConfigError(
            f"{source}: the campaign expands to {total:,} missions, more than the {MAX_MISSIONS:,} "
            "one campaign may hold; split it (or fly its first missions with --limit)"
        )
    return wanted


def _preset_groups(spec: CampaignSpec, base_preset: str, source: str) -> _Groups:
    """The campaign's groups in order, each preset known and each label listed once."""
    from alight.mission.presets import PRESETS  # late import: presets import the blocks

    entries = list(spec.presets) if spec.presets is not None else [base_preset]
    groups: _Groups = {}
    for e in entries:
        label, preset_name, blocks = (
            (e, e, {}) if isinstance(e, str) else (e.name, e.preset or base_preset, dict(e.blocks))
        )
        if preset_name not in PRESETS:
            raise ConfigError(
                f"{source}: presets: unknown preset '{preset_name}', expected one of {sorted(PRESETS)}"
            )
        if label in groups:
            raise ConfigError(f"{source}: presets: '{label}' is listed twice")
        groups[label] = (preset_name, blocks)
    return groups


def _swept_parameters(
    spec: CampaignSpec, base_tree: Mapping[str, Any], source: str
) -> tuple[list[str], dict[str, _Dist], int]:
    """The swept paths (grid, conditions, then sampled ones), each checked against the scenario's keys;
    the sampled ones' distributions and the number of draws per condition (0 without ``sample``)."""
    paths: list[str] = []
    for key in spec.grid:
        _check_path(base_tree, key, f"{source}: grid")
        paths.append(key)
    for i, cond in enumerate(spec.conditions):
        if not cond:
            raise ConfigError(f"{source}: conditions[{i}]: an empty condition (set at least one parameter)")
        for key in cond:
            _check_path(base_tree, key, f"{source}: conditions[{i}]")
            if key not in paths:
                paths.append(key)
    dists: dict[str, _Dist] = {}
    n_draws = 0
    if spec.sample is not None:
        sample = dict(spec.sample)
        n = sample.pop("n", None)
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ConfigError(f"{source}: sample.n: the number of draws must be an integer >= 1, got {n!r}")
        if not sample:
            raise ConfigError(f"{source}: sample: no parameter to sample")
        n_draws = n
        for key, raw in sample.items():
            _check_path(base_tree, key, f"{source}: sample")
            if key in paths:
                raise ConfigError(f"{source}: sample: '{key}' is also set by the grid or the conditions")
            try:
                dists[key] = _DISTRIBUTION.validate_python(raw)
            except ValidationError as err:
                raise ConfigError(_format_validation(f"{source}: sample.{key}", err)) from None
            paths.append(key)
    for a in paths:
        for b in paths:
            if a != b and b.startswith(a + "."):
                raise ConfigError(f"{source}: '{a}' and '{b}' overlap: sweep one or the other")
    return paths, dists, n_draws


def _raw_conditions(
    spec: CampaignSpec, dists: Mapping[str, _Dist], n_draws: int, n_conditions: int, source: str
) -> list[dict[str, Any]]:
    """The first ``n_conditions`` conditions (dotted path -> value) in expansion order. The grid's
    product and the draws are walked lazily: a limit on a huge grid or a huge ``sample.n`` expands only
    its head, and the draws it makes are the same as the full expansion's first ones (one generator,
    drawn condition by condition, parameter by parameter)."""
    n_base = -(-n_conditions // n_draws) if n_draws else n_conditions
    raw: list[dict[str, Any]] = []
    if spec.grid:
        keys = list(spec.grid)
        raw += [
            dict(zip(keys, combo, strict=True))
            for combo in itertools.islice(itertools.product(*spec.grid.values()), n_base)
        ]
    raw += [dict(c) for c in spec.conditions[: max(0, n_base - len(raw))]]
    seen: dict[str, int] = {}
    for i, cond in enumerate(raw):
        key = json.dumps(cond, sort_keys=True)
        if key in seen:
            raise ConfigError(
                f"{source}: condition c{i:03d} ({_short(cond)}) repeats c{seen[key]:03d}; "
                "more replicates come from seeds_per_condition"
            )
        seen[key] = i
    if not raw:
        raw = [{}]
    if not dists:
        return raw
    rng = sample_rng(spec.seed)
    draws = (
        {**cond, **{key: _draw(d, rng) for key, d in dists.items()}} for cond in raw for _ in range(n_draws)
    )
    return list(itertools.islice(draws, n_conditions))


def _validated_conditions(
    raw_conditions: list[dict[str, Any]],
    base_tree: Mapping[str, Any],
    groups: _Groups,
    paths: list[str],
    source: str,
) -> tuple[list[Condition], list[dict[str, Any]]]:
    """Each condition's scenario tree, validated for every group (one ``ConfigError`` naming the
    condition), and the condition with its parameters as the scenario holds them."""
    conditions: list[Condition] = []
    trees: list[dict[str, Any]] = []
    for index, cond in enumerate(raw_conditions):
        cid = f"c{index:03d}"
        tree = copy.deepcopy(dict(base_tree))
        for key, value in cond.items():
            _set(tree, key, value)
        for preset in groups:
            try:
                checked = Scenario.model_validate(_grouped(tree, *groups[preset]))
            except ValidationError as err:
                what = f"condition {cid} ({_short(cond)})" if cond else f"condition {cid}"
                raise ConfigError(_format_validation(f"{source}: {what}, preset {preset}", err)) from None
        # Values as the scenario holds them (e.g. an int given for a float), so results.csv shows them
        # in the same form as result.json.
        dumped = checked.model_dump(mode="json")
        dumped["blocks"] = copy.deepcopy(tree.get("blocks"))  # without the last group's block set
        params = {p: _get(dumped, p) for p in paths}
        conditions.append(Condition(index, cid, params))
        trees.append(dumped)
    return conditions, trees


def _planned_missions(
    spec: CampaignSpec,
    conditions: list[Condition],
    trees: list[dict[str, Any]],
    groups: _Groups,
    paths: list[str],
    wanted: int,
) -> list[PlannedMission]:
    """The first ``wanted`` missions: condition by condition, replicate by replicate, group by group."""
    # The seed branch of a condition: its index among the distinct conditions once the parameters that
    # keep the seeds are left out (the condition's own index when there are none).
    seed_index: dict[tuple[tuple[str, str], ...], int] = {}
    missions: list[PlannedMission] = []
    for condition, tree in zip(conditions, trees, strict=True):
        seed_key = tuple(
            (p, repr(v)) for p, v in sorted(condition.params.items()) if p not in spec.same_seeds_across
        )
        branch = (
            seed_index.setdefault(seed_key, len(seed_index)) if spec.same_seeds_across else condition.index
        )
        for r in range(spec.seeds_per_condition):
            if len(missions) >= wanted:
                break  # the limit is reached: the rest is never expanded
            seed = mission_seed(spec.seed, branch, r)
            for preset in groups:
                mid = mission_id(condition.condition_id, preset, r)
                scenario = _grouped(tree, *groups[preset])
                scenario["seed"] = seed
                if "name" not in paths:
                    scenario["name"] = f"{spec.name} {mid}"
                missions.append(
                    PlannedMission(
                        mid,
                        condition.condition_id,
                        condition.index,
                        preset,
                        r,
                        seed,
                        condition.params,
                        scenario,
                    )
                )
    return missions[:wanted]


def campaign_from_dict(
    data: Any,
    source: str = "campaign",
    *,
    base_dir: Path | None = None,
    text: str | None = None,
    path: Path | None = None,
    limit: int | None = None,
) -> Campaign:
    """Validate and expand a campaign mapping; any problem becomes one ``ConfigError`` line.

    ``base_dir`` resolves a ``base`` given as a file name (default: the working directory); ``limit``
    expands only the first ``limit`` missions (:func:`expand_campaign`).
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of campaign keys, got {type(data).__name__}")
    try:
        spec = CampaignSpec.model_validate(data)
    except ValidationError as err:
        raise ConfigError(_format_validation(source, err)) from None
    conditions, missions, paths, presets = expand_campaign(
        spec, source=source, base_dir=base_dir, limit=limit
    )
    return Campaign(spec, conditions, missions, paths, presets, source=path, text=text)


def read_campaign_spec(path: str | Path) -> tuple[CampaignSpec, Any, str]:
    """The campaign file's validated spec, its data and text, without expanding it; ``ConfigError``."""
    p = Path(path)
    data, text = read_yaml_file(p, "campaign")
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: expected a mapping of campaign keys, got {type(data).__name__}")
    try:
        spec = CampaignSpec.model_validate(data)
    except ValidationError as err:
        raise ConfigError(_format_validation(str(p), err)) from None
    return spec, data, text


def load_campaign(path: str | Path, *, limit: int | None = None) -> Campaign:
    """Read, validate and expand a campaign YAML file (only its first ``limit`` missions when given);
    any problem becomes one ``ConfigError`` line."""
    p = Path(path)
    _, data, text = read_campaign_spec(p)
    return campaign_from_dict(data, str(p), base_dir=p.resolve().parent, text=text, path=p, limit=limit)
