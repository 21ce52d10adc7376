"""National Instruments TDMS files (``.tdms``), streamed through ``npTDMS``.

A channel is named ``group/channel``, or by its channel name alone when no other group has a
channel so called. Time: a channel, or, when the dataset's time column (``t`` unless mapped
under ``columns:``) names no channel, the **waveform time** built from the waveform timing of
the other channels read (properties ``wf_start_offset`` and ``wf_increment``, in s; every
channel read must carry the same timing): ``t = wf_start_offset + i * wf_increment``.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from spa.datasets.contract import _BATCH_ROWS
from spa.datasets.problems import _suggest
from spa.datasets.readers.base import Source, _Chunk, _ReadError

#: The name under which the waveform time is resolved.
WAVEFORM_TIME = "waveform time (wf_start_offset + i * wf_increment)"

_LISTED = 12


class _TdmsSource(Source):
    """A TDMS file: channels by ``group/channel`` or unique channel name; waveform time."""

    what = "LabVIEW channel"

    def __init__(self, path: Path, options: Mapping[str, Any] | None = None) -> None:
        from nptdms import TdmsFile

        self.path = path
        try:
            self.file = TdmsFile.open(path)
            self.channels = {
                f"{g.name}/{c.name}": c for g in self.file.groups() for c in g.channels()
            }
        except Exception as exc:  # npTDMS raises several types for a damaged file
            raise _ReadError(
                f"unreadable TDMS file (truncated, damaged or not TDMS?): "
                f"{type(exc).__name__}: {exc}; copy it again from the acquisition PC"
            ) from exc
        self.columns = list(self.channels)

    def _timing(self, key: str) -> tuple[float, float] | None:
        props = self.channels[key].properties
        if "wf_increment" not in props:
            return None
        return float(props.get("wf_start_offset", 0.0)), float(props["wf_increment"])

    def resolve(self, name: str) -> str | None:
        """The channel (``group/channel``) called ``name``; None when absent; raises when a
        bare channel name is in several groups. A missing ``t`` is the waveform time."""
        if name in self.channels:
            return name
        short = [k for k, c in self.channels.items() if c.name == name]
        if len(short) > 1:
            raise _ReadError(
                f"channel name {name!r} is in several groups ({', '.join(map(repr, short))}); "
                "name it as 'group/channel' under columns: in dataset.yaml",
                column=name,
            )
        if short:
            return short[0]
        if name == "t" and any(self._timing(k) for k in self.channels):
            return WAVEFORM_TIME
        return None

    def describe(self, name: str) -> str:
        """The channels the file holds and the closest to ``name``."""
        names = list(self.channels)
        more = f", ... ({len(names)} in all)" if len(names) > _LISTED else ""
        listed = ", ".join(repr(n) for n in names[:_LISTED]) + more
        shorts = [c.name for c in self.channels.values()]
        timing = "" if any(self._timing(k) for k in names) else " and no waveform timing"
        return f"; the file has the channels {listed}{timing}" + _suggest(name, names + shorts)

    def check_types(self, names: list[str]) -> list[_ReadError]:
        errors = []
        lengths: dict[str, int] = {}
        timings: dict[str, tuple[float, float] | None] = {}
        for name in names:
            key = self.resolve(name)
            if key == WAVEFORM_TIME:
                continue
            assert key is not None
            channel = self.channels[key]
            timings[name] = self._timing(key)
            if np.dtype(channel.dtype).kind not in "biuf":
                errors.append(
                    _ReadError(
                        f"LabVIEW channel {key!r} holds {channel.dtype}, not numbers; "
                        "expected a numeric channel",
                        column=name,
                    )
                )
            lengths[name] = len(channel)
        if len(set(lengths.values())) > 1:
            sizes = ", ".join(f"{k}: {v}" for k, v in lengths.items())
            errors.append(
                _ReadError(f"LabVIEW channels have different lengths ({sizes}); expected one")
            )
        waveform = [n for n in names if self.resolve(n) == WAVEFORM_TIME]
        if waveform and (None in timings.values() or len(set(timings.values())) > 1):
            found = ", ".join(f"{k}: {v or 'none'}" for k, v in timings.items())
            errors.append(
                _ReadError(
                    "no time channel, and the channels read do not share one waveform timing "
                    f"(wf_start_offset, wf_increment) to build it from ({found}); name the time "
                    "channel under columns: in dataset.yaml",
                    column=waveform[0],
                )
            )
        return errors

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        keys = {n: self.resolve(n) for n in names}
        data = [k for k in keys.values() if k != WAVEFORM_TIME]
        n = len(self.channels[data[0]]) if data else 0
        timing = self._timing(data[0]) if data else None
        start0, step = timing if timing is not None else (0.0, 1.0)
        for start in range(0, n, _BATCH_ROWS):
            stop = min(start + _BATCH_ROWS, n)
            values = {}
            for name, key in keys.items():
                if key == WAVEFORM_TIME:
                    values[name] = start0 + step * np.arange(start, stop, dtype=np.float64)
                else:
                    values[name] = np.asarray(self.channels[key][start:stop], dtype=np.float64)
            yield start, values, {}
