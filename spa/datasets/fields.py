"""Checks of ``dataset.yaml``'s values, one key at a time: each returns the value it keeps
and the problems it found, in words that name what was expected (:mod:`spa.datasets.spec`
gathers them for the whole file)."""

from __future__ import annotations

import datetime
import math
from collections.abc import Mapping
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any

from spa.datasets.contract import _FORMATS, _NAME_RE, ORIGINS
from spa.datasets.problems import _is_one_of, _one_of, _suggest
from spa.model.modulators import MODULATORS, check_settings

__all__ = ["recorded_date"]


def _check_modulator(value: Any) -> tuple[dict[str, Any] | None, list[str]]:
    """Check a ``modulator:`` mapping; return the completed settings and the problems."""
    example = "e.g. {type: pwm, f_w: 20}"
    if not isinstance(value, Mapping):
        return None, [f"modulator must be a mapping, {example}; got {value!r}"]
    kind = value.get("type")
    if kind is None:
        return None, [f"modulator has no 'type'; expected one of {_one_of(MODULATORS)}, {example}"]
    if not _is_one_of(kind, MODULATORS):
        return None, [
            f"unknown modulator type {kind!r}; expected one of {_one_of(MODULATORS)}"
            f"{_suggest(kind, MODULATORS)}"
        ]
    allowed = ["type", *MODULATORS[kind]]
    problems = [
        f"unknown {kind} setting {k!r}{_suggest(k, allowed)}; {kind} takes {_one_of(allowed)}"
        for k in value
        if k not in allowed
    ]
    if problems:
        return None, problems
    settings = {k: v for k, v in value.items() if k != "type"}
    try:
        full = check_settings(str(kind), **settings)
    except ValueError as exc:
        return None, [f"bad modulator settings: {exc}"]
    return {"type": kind, **full}, []


def _check_controller(value: Any) -> tuple[dict[str, Any] | None, list[str]]:
    """Check a closed-loop run's ``controller:``; return it (floats, lists) and the problems."""
    from spa.closedloop.controller import PIController

    example = "e.g. {kp: 4.0, ki: 4.5, dt: 0.001}"
    if not isinstance(value, Mapping):
        return None, [f"controller must be a mapping, {example}; got {value!r}"]
    unknown = sorted(set(value) - {"kp", "ki", "dt", "schedule", "feedforward"})
    if unknown or "kp" not in value or "dt" not in value:
        what = f"unknown key(s) {unknown}" if unknown else "kp and dt are required"
        keys = "kp, ki, dt, schedule, feedforward"
        return None, [f"bad controller ({what}); expected {keys}, {example}"]
    try:
        dt = float(value["dt"])
        if not (math.isfinite(dt) and 0.0 < dt <= 1.0):
            raise ValueError(f"dt = {value['dt']!r} must be a step in s, in (0, 1]")
        ctrl = PIController.from_mapping(dict(value))
    except (TypeError, ValueError, KeyError) as exc:
        return None, [f"bad controller: {exc}"]
    return {**ctrl.to_mapping(), "dt": dt}, []


def _check_run_file(folder: Path, value: Any) -> tuple[str | None, str | None]:
    """Check a run's ``file``: return (relative path, None) or (None, problem)."""
    if not isinstance(value, str) or not value.strip():
        return None, f"file must be a path relative to the dataset folder, got {value!r}"
    if "\\" in value:
        return None, f"file path {value!r} contains '\\'; use '/' between folders"
    if PurePosixPath(value).is_absolute() or PureWindowsPath(value).drive:
        return None, (
            f"file path {value!r} is absolute; paths must be relative to the dataset folder "
            "and stay inside it"
        )
    if ".." in PurePosixPath(value).parts:
        return None, (
            f"file path {value!r} leaves the dataset folder through '..'; "
            "data files must live inside the folder"
        )
    full = folder / value
    resolved = full.resolve()
    if not resolved.is_relative_to(folder.resolve()):
        return None, (
            f"file path {value!r} resolves to {resolved}, outside the dataset folder "
            "(a symlink pointing out?); data files must live inside the folder"
        )
    suffix = PurePosixPath(value).suffix.lower()
    if suffix not in _FORMATS:
        return None, (
            f"unsupported file type {suffix or '(none)'!r} for {value!r}; expected one of "
            f"{_one_of(_FORMATS)}"
        )
    if not full.exists():
        return None, f"file {value!r} not found (looked for {full})"
    if not full.is_file():
        return None, f"{value!r} is not a regular file"
    return value, None


def _name_problem(name: Any, folder_name: str) -> str | None:
    """What is wrong with the dataset's ``name:`` in the folder ``folder_name``, or None."""
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name) or name in (".", ".."):
        return f"name {name!r} must be a string of letters, digits, '.', '_' and '-'"
    if name != folder_name:
        return f"name {name!r} differs from the folder name {folder_name!r}; they must be equal"
    return None


def _description_problem(desc: Any) -> str | None:
    """What is wrong with ``description:``, or None."""
    if not isinstance(desc, str) or not desc.strip():
        return f"description must be non-empty text, got {desc!r}"
    return None


def _origin_problem(origin: Any) -> str | None:
    """What is wrong with ``origin:``, or None."""
    if not _is_one_of(origin, ORIGINS):
        return f"origin {origin!r} is not one of {_one_of(ORIGINS)}{_suggest(origin, ORIGINS)}"
    return None


def _rig_problem(rig: Any) -> str | None:
    """What is wrong with ``rig:``, or None."""
    if not isinstance(rig, Mapping):
        return (
            "rig must be a mapping describing the bench, e.g. "
            f"{{valve: ..., actuator: ..., sensors: ..., controller: ...}}; got {rig!r}"
        )
    return None


def recorded_date(value: Any) -> str:
    """The ISO 8601 day (``YYYY-MM-DD``) of a ``recorded:`` value: a date, a date and time, or
    text starting with one (YAML reads ``2025-03-01`` as a date).

    Raises
    ------
    ValueError
        If it is none of these.

    Examples
    --------
    >>> recorded_date("2025-03-01T14:02:00"), recorded_date(datetime.date(2025, 3, 1))
    ('2025-03-01', '2025-03-01')
    """
    if isinstance(value, datetime.datetime):
        return value.date().isoformat()
    if isinstance(value, datetime.date):
        return value.isoformat()
    if isinstance(value, str):
        return datetime.date.fromisoformat(value.strip()[:10]).isoformat()
    raise ValueError(f"not a date: {value!r}")


def recorded_stamp(value: Any) -> str:
    """A ``recorded:`` value as the overview orders sessions by: its day (``YYYY-MM-DD``),
    and its time to the minute when it has one (``YYYY-MM-DDTHH:MM``, UTC when it names its
    zone), so that sessions of one day keep the order they were recorded in.

    Raises
    ------
    ValueError
        If it is not a date (:func:`recorded_date`).

    Examples
    --------
    >>> recorded_stamp("2025-03-01"), recorded_stamp(datetime.date(2025, 3, 1))
    ('2025-03-01', '2025-03-01')
    >>> recorded_stamp("2025-03-01T14:02:31+01:00"), recorded_stamp("2025-03-01 09:05")
    ('2025-03-01T13:02', '2025-03-01T09:05')
    """
    day = recorded_date(value)
    when = value
    if isinstance(value, str) and len(value.strip()) > 10:
        try:
            when = datetime.datetime.fromisoformat(value.strip())
        except ValueError:
            return day
    if not isinstance(when, datetime.datetime):
        return day
    if when.tzinfo is not None:
        when = when.astimezone(datetime.UTC)
    return when.strftime("%Y-%m-%dT%H:%M")


def _recorded_problem(value: Any) -> str | None:
    """What is wrong with ``recorded:``, or None."""
    try:
        recorded_date(value)
    except ValueError:
        return f"recorded must be an ISO 8601 date such as 2025-03-01, got {value!r}"
    return None
