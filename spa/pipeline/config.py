"""Configuration checking: every problem named by its key, with what is allowed."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from spa._checks import MAX_GRID_VALUES, MAX_SWEEP_POINTS
from spa.io import read_yaml

__all__ = [
    "MAX_GRID_VALUES",
    "MAX_RUN_SAMPLES",
    "MAX_SWEEP_POINTS",
    "ConfigError",
    "config_errors",
    "discover_datasets",
    "figure_datasets",
    "grid_errors",
    "validate_config",
]

#: Most samples of one simulated run (an experiment at the controller step): 400 MB per array.
MAX_RUN_SAMPLES = 50_000_000


class ConfigError(ValueError):
    """Raised when a configuration does not match its schema; lists every problem."""


def _key(path: Any) -> str:
    parts: list[str] = []
    for item in path:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        else:
            parts.append(("." if parts else "") + str(item))
    return "".join(parts) or "<top level>"


def config_errors(config: Mapping[str, Any], schema: Mapping[str, Any]) -> list[str]:
    """Return one readable line per schema violation of ``config`` (empty when valid).

    Parameters
    ----------
    config : mapping
        The configuration, as loaded from YAML.
    schema : mapping
        A JSON schema (draft 2020-12).

    Returns
    -------
    list of str
        ``"<key>: <problem>"`` lines, sorted by key, where ``<key>`` is the dotted path to the
        offending value (e.g. ``analytic.sweeps.pwm.step``).
    """
    from jsonschema import Draft202012Validator

    validator = Draft202012Validator(schema)
    lines = []
    for err in validator.iter_errors(dict(config)):
        if err.validator in ("allOf", "if", "then"):
            continue
        where = _key(err.absolute_path)
        msg = err.message
        if err.validator == "additionalProperties":
            allowed = sorted(err.schema.get("properties", {}))
            msg = f"{msg}; allowed keys: {allowed}"
        elif err.validator == "anyOf":
            keys = [" and ".join(b.get("required", [])) for b in err.validator_value]
            msg = f"needs {' or '.join(k for k in keys if k)}"
        elif err.validator == "enum":
            msg = f"{err.instance!r} is not one of {err.validator_value}"
        lines.append(f"{where}: {msg}")
    return sorted(set(lines)) or semantic_errors(config)


def semantic_errors(config: Mapping[str, Any]) -> list[str]:
    """What a schema cannot say: relations between values of a schema-valid configuration.

    - each sweep of ``analytic.sweeps`` (and ``tuning.sweeps`` when present) runs upwards:
      ``start < stop``;
    - a simulated dataset's logging period ``1/sensor.fs`` is a whole number of controller
      steps ``controller_dt`` (samples fall on the modulator's clock);
    - a simulated dataset with a physical ``plant`` sets its sensor's noise and ADC step
      there, not under ``sensor`` (which keeps ``fs``);
    - its modulators are valid for that controller (:meth:`Modulator.from_mapping` and the
      step checks of :func:`spa.model.modulators.check_settings`).

    Returns
    -------
    list of str
        ``"<key>: <problem>"`` lines, empty when the configuration is consistent.
    """
    from spa.model.modulators import Modulator, check_settings

    lines = grid_errors(config)
    for section in ("analytic", "tuning"):
        sweeps = (config.get(section) or {}).get("sweeps") or {}
        for kind, grid in sweeps.items():
            if isinstance(grid, Mapping) and {"start", "stop"} <= set(grid):
                if not grid["start"] < grid["stop"]:
                    lines.append(
                        f"{section}.sweeps.{kind}: start {grid['start']} must be below stop "
                        f"{grid['stop']}"
                    )
    for name, sim in (config.get("simulated") or {}).items():
        if sim is None:  # dropped by a configuration merged over this one
            continue
        dt = float(sim["controller_dt"])
        fs = float(sim["sensor"]["fs"])
        lines += _plant_errors(name, sim)
        ratio = 1.0 / (fs * dt)
        if abs(ratio - round(ratio)) > 1e-9 * max(ratio, 1.0) or round(ratio) < 1:
            lines.append(
                f"simulated.{name}.sensor.fs: the logging period 1/fs = {1 / fs:g} s is not a "
                f"whole number of controller steps controller_dt = {dt:g} s"
            )
        for i, mod in enumerate(sim.get("modulators") or []):
            try:
                setting = Modulator.from_mapping(mod)
                check_settings(setting.kind, dt, **setting.settings)
            except ValueError as exc:
                lines.append(f"simulated.{name}.modulators[{i}]: {exc}")
    return lines


def _plant_errors(name: str, sim: Mapping[str, Any]) -> list[str]:
    """A physical plant's settings together (its sensor replaces ``sensor:`` but ``fs``)."""
    if sim.get("plant") is None:
        return []
    from spa.synthetic.physical import PhysicalPlant

    lines = [
        f"simulated.{name}.sensor.{key}: with a physical plant the sensor's {key} is set in "
        f"simulated.{name}.plant (noise, quantum, sensor_lag, mains); sensor: keeps fs only"
        for key in ("noise", "quantum", "ringing")
        if key in sim["sensor"]
    ]
    try:
        PhysicalPlant.from_mapping(sim["plant"])
    except ValueError as exc:
        lines.append(f"simulated.{name}.plant: {exc}")
    return lines


def _points(grid: Mapping[str, Any]) -> int:
    """Points of a sweep ``{start, stop, step}`` (as :func:`spa.tuning.cost.sweep_grid`)."""
    return int((float(grid["stop"]) - float(grid["start"])) / float(grid["step"]) + 1e-9) + 1


def _mb(values: float) -> str:
    return f"{values * 8 / 1e6:,.0f} MB"


def grid_errors(config: Mapping[str, Any]) -> list[str]:
    """Sweeps, grids and runs too large to compute, and accepted ranges that are empty.

    Checked before anything runs, so that a runaway setting (a sweep step of 1e-7, ``n_xi`` of
    1e9) is one configuration error naming its key rather than a job that allocates
    gigabytes and dies. The bounds are :data:`MAX_SWEEP_POINTS` points a sweep,
    :data:`MAX_GRID_VALUES` values of sweep points x ``n_xi`` (the cost's arrays) and
    :data:`MAX_RUN_SAMPLES` samples a simulated run.

    Returns
    -------
    list of str
        ``"<key>: <problem>"`` lines, empty when every grid is bounded.

    Examples
    --------
    >>> grid_errors({"analytic": {"n_xi": 100,
    ...     "sweeps": {"pwm": {"start": 1.0, "stop": 80.0, "step": 1e-7}}}})[0][:60]
    'analytic.sweeps.pwm.step: 1e-07 gives 790,000,001 points; at'
    >>> grid_errors({"tuning": {"ranges": {"pwm": [50.0, 5.0]}}})
    ['tuning.ranges.pwm: [50.0, 5.0]: the lower bound 50.0 is above the upper bound 5.0']
    """
    lines = []
    analytic = config.get("analytic") or {}
    tuning = config.get("tuning") or {}
    n_xi = int(analytic.get("n_xi") or 2)
    grids = {f"analytic.sweeps.{k}": g for k, g in (analytic.get("sweeps") or {}).items()}
    if isinstance(tuning.get("gain_sweep"), Mapping):
        grids["tuning.gain_sweep"] = tuning["gain_sweep"]
    points: dict[str, int] = {}
    for key, grid in grids.items():
        if not (isinstance(grid, Mapping) and {"start", "stop", "step"} <= set(grid)):
            continue
        n = points[key] = max(_points(grid), 1)
        if n > MAX_SWEEP_POINTS:
            lines.append(
                f"{key}.step: {grid['step']} gives {n:,} points; at most "
                f"{MAX_SWEEP_POINTS:,} (a coarser step or a shorter range)"
            )
        elif n * n_xi > MAX_GRID_VALUES and key.startswith("analytic"):
            lines.append(
                f"analytic.n_xi: {n_xi:,} x the {n:,} points of {key} = {n * n_xi:,} values "
                f"(about {_mb(n * n_xi)} an array); at most {MAX_GRID_VALUES:,}"
            )
    gains = points.get("tuning.gain_sweep", 1)
    from spa.model.modulators import REGISTRY

    for name, kind in REGISTRY.items():
        swept = points.get(f"analytic.sweeps.{name}", 1)
        if (
            kind.gain_swept
            and 1 < gains <= MAX_SWEEP_POINTS
            and gains * swept * n_xi > MAX_GRID_VALUES
        ):
            lines.append(
                f"tuning.gain_sweep: {gains:,} gains x {swept:,} {kind.parameter} x n_xi "
                f"{n_xi:,} = {gains * swept * n_xi:,} values (about "
                f"{_mb(gains * swept * n_xi)}); at most {MAX_GRID_VALUES:,}"
            )
    for kind, bounds in (tuning.get("ranges") or {}).items():
        if isinstance(bounds, list) and len(bounds) == 2 and bounds[0] > bounds[1]:
            lines.append(
                f"tuning.ranges.{kind}: {bounds}: the lower bound {bounds[0]} is above the "
                f"upper bound {bounds[1]}"
            )
    supply = (config.get("datasets") or {}).get("plausible_supply_bar")
    if isinstance(supply, list) and len(supply) == 2 and not supply[0] < supply[1]:
        lines.append(
            f"datasets.plausible_supply_bar: {supply}: the lower bound must be below the upper"
        )
    stair = tuning.get("staircase") or {}
    if {"step", "hold", "dt"} <= set(stair):
        n = (1 / float(stair["step"]) + 1) * float(stair["hold"]) / float(stair["dt"])
        if n > MAX_RUN_SAMPLES:
            lines.append(
                f"tuning.staircase: {n:,.0f} samples (levels x hold / dt); at most "
                f"{MAX_RUN_SAMPLES:,}"
            )
    lines += _run_size_errors(config)
    return lines


def _run_size_errors(config: Mapping[str, Any]) -> list[str]:
    """Simulated runs longer than :data:`MAX_RUN_SAMPLES` at a dataset's controller step."""
    exp = config.get("experiments") or {}
    seconds = {}
    stair = exp.get("staircase") or {}
    if {"step", "hold"} <= set(stair):
        seconds["staircase"] = (1 / float(stair["step"]) + 1) * float(stair["hold"])
    sine = exp.get("sine") or {}
    if {"frequency", "amplitudes"} <= set(sine):
        per = float(sine.get("periods_per_level", 1)) / float(sine["frequency"])
        seconds["sine"] = len(sine["amplitudes"]) * (per + float(sine.get("settle", 0)))
    if "duration" in (exp.get("chirp") or {}):
        seconds["chirp"] = float(exp["chirp"]["duration"])
    steps = {
        name: float(sim.get("controller_dt") or 0)
        for name, sim in (config.get("simulated") or {}).items()
        if sim is not None and float(sim.get("controller_dt") or 0) > 0
    }
    lines = []
    for kind, length in seconds.items():
        over = sorted((dt, name) for name, dt in steps.items() if length / dt > MAX_RUN_SAMPLES)
        if over:  # one line per experiment, at the finest controller step
            dt, name = over[0]
            more = f" (and {len(over) - 1} more simulated datasets)" if len(over) > 1 else ""
            lines.append(
                f"experiments.{kind}: a run of {length:,.0f} s is {length / dt:,.0f} samples "
                f"at simulated.{name}.controller_dt = {dt:g} s{more}; at most {MAX_RUN_SAMPLES:,}"
            )
    return lines


def _resolve(schema: Mapping[str, Any], root: Mapping[str, Any]) -> Mapping[str, Any]:
    ref = schema.get("$ref")
    if isinstance(ref, str) and ref.startswith("#/"):
        node: Any = root
        for part in ref[2:].split("/"):
            node = node[part]
        return _resolve(node, root)
    return schema


def _scalar(text: str) -> Any:
    """``text`` read as a YAML scalar or flow collection (``'0.03'`` -> 0.03, ``'null'`` ->
    None); YAML 1.1 misses ``1e-3``, read as a float. Unreadable text stays a string."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    if isinstance(value, str):
        try:
            return float(text)
        except ValueError:
            return text
    return value


def _types(schema: Mapping[str, Any], root: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    """The alternatives of ``schema``: itself, or each branch of its ``oneOf``/``anyOf``."""
    branches = schema.get("oneOf") or schema.get("anyOf")
    if branches and "type" not in schema:
        return [_resolve(b, root) for b in branches]
    return [schema]


def _fits(value: Any, kind: Any) -> bool:
    """Whether ``value`` (a parsed YAML value) is of the JSON-schema ``type`` ``kind``."""
    kinds = kind if isinstance(kind, list) else [kind]
    for k in kinds:
        if k == "null" and value is None:
            return True
        if k == "boolean" and isinstance(value, bool):
            return True
        if isinstance(value, bool):
            continue
        if k == "number" and isinstance(value, int | float):
            return True
        if k == "integer" and isinstance(value, int | float) and float(value).is_integer():
            return True
        if k == "array" and isinstance(value, list):
            return True
        if k == "object" and isinstance(value, dict):
            return True
    return False


def _coerce(value: Any, schema: Mapping[str, Any], root: Mapping[str, Any]) -> Any:
    """One value: a string read as the YAML value its schema wants, or a container walked into.

    A string is replaced only where no alternative of the schema takes a string (``type``
    without ``string``, no ``enum`` holding it) and its YAML reading is of a type one
    alternative takes; containers are then walked with that alternative's schema.
    """
    options = _types(schema, root)
    if isinstance(value, str):
        for option in options:
            kind = option.get("type")
            takes_string = kind is None or "string" in (kind if isinstance(kind, list) else [kind])
            if value in (option.get("enum") or ()) or ("enum" not in option and takes_string):
                return value
        for option in options:
            parsed = _scalar(value)
            if option.get("type") is not None and _fits(parsed, option["type"]):
                if option["type"] == "integer" or (
                    isinstance(option["type"], list)
                    and "integer" in option["type"]
                    and "number" not in option["type"]
                ):
                    parsed = int(parsed) if isinstance(parsed, float) else parsed
                return coerce_numbers(parsed, option, root)
        return value
    for option in options:
        kind = option.get("type")
        if kind is None or _fits(value, kind):
            return coerce_numbers(value, option, root)
    return value


def coerce_numbers(config: Any, schema: Mapping[str, Any], root: Mapping[str, Any] | None = None):
    """Read strings as the YAML values the schema wants there, in place.

    Snakemake reads a nested ``--config`` value with YAML's base loader, so
    ``'tuning={score: J_exact, max_chattering: 0.03}'`` hands over ``'0.03'`` (and ``'null'``,
    ``'true'``, ``'[5, 50]'``' items) as strings; a user means the number. A string is read as
    YAML only at a key whose schema takes no string, and only when what it reads as is of a
    type the schema takes (a number, an integer, null, a boolean, a list or a mapping, whose
    items are then read in turn); anything else is left for the schema to report.

    Examples
    --------
    >>> cfg = {"a": {"n": "50", "x": "1e-3", "name": "50", "m": "null"}}
    >>> schema = {"properties": {"a": {"properties": {
    ...     "n": {"type": "integer"}, "x": {"type": "number"}, "name": {"type": "string"},
    ...     "m": {"type": ["number", "null"]}}}}}
    >>> coerce_numbers(cfg, schema)
    {'a': {'n': 50, 'x': 0.001, 'name': '50', 'm': None}}
    """
    root = schema if root is None else root
    node = _resolve(schema, root)
    if isinstance(config, dict):
        props = dict(node.get("properties", {}))
        for branch in node.get("allOf", []):  # if/then variants (a modulator by its type)
            then = _resolve(branch.get("then", branch), root)
            for key, sub in then.get("properties", {}).items():
                if isinstance(sub, Mapping):
                    props.setdefault(key, sub)
        extra = node.get("additionalProperties")
        for key, value in config.items():
            sub = props.get(key, extra if isinstance(extra, Mapping) else None)
            if sub is not None:
                config[key] = _coerce(value, _resolve(sub, root), root)
    elif isinstance(config, list) and isinstance(node.get("items"), Mapping):
        sub = _resolve(node["items"], root)
        for i, value in enumerate(config):
            config[i] = _coerce(value, sub, root)
    return config


def validate_config(config: Mapping[str, Any], schema_path: str | Path) -> None:
    """Check ``config`` against the YAML JSON-schema at ``schema_path``.

    Values given as strings (``--config`` on the command line) are first read as the YAML
    values the schema wants there (:func:`coerce_numbers`), in place.

    Raises
    ------
    ConfigError
        Listing every problem, each naming its key and what is allowed.
    """
    schema = read_yaml(schema_path)
    coerce_numbers(config, schema)
    errors = config_errors(config, schema)
    if errors:
        raise ConfigError(
            f"invalid configuration (checked against {schema_path}):\n  " + "\n  ".join(errors)
        )


def discover_datasets(config: Mapping[str, Any]) -> tuple[list[str], list[str]]:
    """The datasets of a run: the simulated ones and the bench ones chosen from ``raw_dir``.

    Parameters
    ----------
    config : mapping
        The validated configuration: ``simulated`` (name -> settings) and ``datasets``
        (``raw_dir``, optional ``include`` and ``exclude`` lists of folder names).

    Returns
    -------
    simulated : list of str
        The names under ``simulated`` whose entry is not null (``name: null`` in a
        configuration merged over another drops that dataset), sorted.
    raw : list of str
        The folders of ``raw_dir`` holding a ``dataset.yaml`` (hidden folders, starting with
        ``.``, are skipped), sorted; only those of ``include`` when it is not empty (in its
        order), minus those of ``exclude``.

    Raises
    ------
    ConfigError
        If ``include`` names a folder that is not a dataset, or a name is both simulated and a
        bench dataset.
    spa.pipeline.safety.UnsafePathError
        If a dataset is named like an entry of the results folder (``logs``, ``analytic``,
        ``report.html``).
    """
    from spa.datasets import find_datasets
    from spa.pipeline.safety import check_dataset_names

    datasets = config["datasets"]
    raw_dir = Path(datasets["raw_dir"])
    found = find_datasets(raw_dir)
    wanted = list(datasets.get("include") or [])
    exclude = set(datasets.get("exclude") or [])
    missing = [d for d in wanted if d not in found]
    if missing:
        raise ConfigError(
            f"config datasets.include names {missing}, but {raw_dir}/ has no such folder "
            f"with a dataset.yaml (found: {found})"
        )
    raw = [d for d in wanted or found if d not in exclude]
    simulated = sorted(d for d, sim in config["simulated"].items() if sim is not None)
    check_dataset_names([*simulated, *raw])
    clash = sorted(set(raw) & set(simulated))
    if clash:
        raise ConfigError(
            f"dataset name(s) {clash} are both simulated (config simulated:) and in {raw_dir}/; "
            "rename one or list it under datasets.exclude"
        )
    return simulated, raw


def figure_datasets(config: Mapping[str, Any], datasets: Sequence[str]) -> list[str]:
    """The datasets whose figures the run draws (config ``figures``).

    Parameters
    ----------
    config : mapping
        The validated configuration; ``figures`` is ``"all"`` (the default), ``"none"`` or a
        list of dataset names.
    datasets : sequence of str
        The datasets of the run (:func:`discover_datasets`).

    Returns
    -------
    list of str
        Those of ``datasets`` that get their figures, in the order of ``datasets``.

    Raises
    ------
    ConfigError
        If the list names a dataset that is not in the run.

    Examples
    --------
    >>> figure_datasets({"figures": ["b"]}, ["a", "b"]), figure_datasets({}, ["a", "b"])
    (['b'], ['a', 'b'])
    """
    chosen = config.get("figures", "all")
    if chosen == "all":
        return list(datasets)
    if chosen == "none":
        return []
    unknown = [name for name in chosen if name not in datasets]
    if unknown:
        raise ConfigError(
            f"config figures names {unknown}, which are not datasets of this run "
            f"(the datasets: {list(datasets)}); use a list of them, 'all' or 'none'"
        )
    return [name for name in datasets if name in chosen]
