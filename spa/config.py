"""Configuration checking: every problem named by its key, with what is allowed."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

__all__ = ["ConfigError", "config_errors", "discover_datasets", "validate_config"]


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
        elif err.validator == "enum":
            msg = f"{err.instance!r} is not one of {err.validator_value}"
        lines.append(f"{where}: {msg}")
    return sorted(set(lines))


def validate_config(config: Mapping[str, Any], schema_path: str | Path) -> None:
    """Check ``config`` against the YAML JSON-schema at ``schema_path``.

    Raises
    ------
    ConfigError
        Listing every problem, each naming its key and what is allowed.
    """
    schema = yaml.safe_load(Path(schema_path).read_text())
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
        The names under ``simulated``, sorted.
    raw : list of str
        The folders of ``raw_dir`` holding a ``dataset.yaml`` (hidden folders, starting with
        ``.``, are skipped), sorted; only those of ``include`` when it is not empty (in its
        order), minus those of ``exclude``.

    Raises
    ------
    ConfigError
        If ``include`` names a folder that is not a dataset, or a name is both simulated and a
        bench dataset.
    spa.safety.UnsafePathError
        If a dataset is named like an entry of the results folder (``logs``, ``analytic``,
        ``report.html``).
    """
    from spa.datasets import find_datasets  # TODO(merge): spa.datasets.select_datasets
    from spa.safety import check_dataset_names

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
    simulated = sorted(config["simulated"])
    check_dataset_names([*simulated, *raw])
    clash = sorted(set(raw) & set(simulated))
    if clash:
        raise ConfigError(
            f"dataset name(s) {clash} are both simulated (config simulated:) and in {raw_dir}/; "
            "rename one or list it under datasets.exclude"
        )
    return simulated, raw
