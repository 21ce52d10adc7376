"""Configuration checking: every problem named by its key, with what is allowed."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

__all__ = ["ConfigError", "config_errors", "validate_config"]


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
