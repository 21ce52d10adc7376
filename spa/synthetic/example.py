"""The example bench export shipped in ``raw/example`` (CSV in ms and kPa, MATLAB, Parquet)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from spa.model.params import ValveParams
from spa.synthetic.runs import identification_runs, modulated_runs, run_seed, simulate_run
from spa.synthetic.sensor import Ringing, Sensor

__all__ = ["EXAMPLE_PARAMS", "write_example_dataset"]

#: The example bench export shipped in ``raw/example`` (see :func:`write_example_dataset`).
EXAMPLE_PARAMS = ValveParams(c1=0.45, k2=1.05, tau2=0.70, t_on=0.004, t_off=0.009)

#: The example's modulated settings and the file format each one's runs are written in.
_MODULATED: tuple[tuple[dict[str, Any], str], ...] = (
    ({"type": "iipfm", "t_l": 0.020, "gain": 1.2}, "mat"),
    ({"type": "pwm", "f_w": 20.0}, "parquet"),
)


def write_example_dataset(folder: str | Path, seed: int = 2025) -> list[Path]:
    """Write a small synthetic dataset laid out the way a real bench export would be.

    It imitates a dSpace/MATLAB bench: identification runs as CSV with time in ms, pressure
    in kPa and the logger's own column names; one staircase as a MATLAB ``.mat`` file; one as
    Parquet; and the ``dataset.yaml`` that maps it all onto the contract. The valve is not
    the paper's (:data:`EXAMPLE_PARAMS`), so identification has something to find.

    Parameters
    ----------
    folder : path-like
        Destination, normally ``raw/example`` (created; existing files are overwritten).
    seed : int
        Noise seed.

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    import scipy.io

    from spa.io import dump_yaml

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = folder.name
    dt = 1e-3
    sensor = Sensor(fs=1000.0, noise=0.004, quantum=0.001, ringing=Ringing(0.008, 70.0, 70.0))
    specs = identification_runs(EXAMPLE_PARAMS, dt, repeats=2)
    modulated = modulated_runs(
        [mod for mod, _ in _MODULATED], dt, {"staircase": {"step": 0.1, "hold": 4.0}}
    )
    formats = {spec.id: fmt for spec, (_, fmt) in zip(modulated, _MODULATED, strict=True)}
    specs += modulated
    rename = {"t": "time_ms", "p": "P_act_kPa", "valve": "valve_cmd", "u": "xi_ref"}
    files = []
    runs_yaml = []
    for spec in specs:
        table = simulate_run(spec, EXAMPLE_PARAMS, dt, sensor, run_seed(seed, name, spec.id))
        table["t"] = np.round(table["t"] * 1000.0, 6)  # ms
        table["p"] = np.round(table["p"] * 100.0, 4)  # kPa
        table = table.rename(columns=rename)
        if spec.kind in ("charge", "discharge", "pulse"):
            fname = f"{spec.id}.csv"
            table.to_csv(folder / fname, index=False, lineterminator="\n")
        elif formats.get(spec.id) == "mat":
            fname = f"{spec.id}.mat"
            scipy.io.savemat(
                folder / fname,
                {c: table[c].to_numpy(np.float64) for c in table.columns},
                do_compression=True,
                oned_as="column",
            )
        else:
            fname = f"{spec.id}.parquet"
            table.to_parquet(folder / fname, index=False)
        files.append(folder / fname)
        entry: dict[str, Any] = {"id": spec.id, "kind": spec.kind, "file": fname}
        if spec.modulator:
            entry["modulator"] = dict(spec.modulator)
        if spec.notes:
            entry["notes"] = spec.notes
        runs_yaml.append(entry)
    doc = {
        "name": name,
        "description": "Example bench export (synthetic, made by `python -m spa example "
        f"raw/{name}`): a valve unlike the paper's, logged at 1 kHz in ms and kPa.",
        "origin": "synthetic",
        "rig": {
            "valve": "3/2 on/off solenoid valve (simulated)",
            "actuator": "bellows SPA (simulated)",
            "sensors": "pressure sensor at the actuator, 1 kHz, 4 mbar noise, 1 mbar ADC step",
            "controller": "1 kHz real-time loop",
            "truth": EXAMPLE_PARAMS.as_dict(),
        },
        "units": {"time": "ms", "pressure": "kPa"},
        "columns": rename,
        "runs": runs_yaml,
    }
    spec_path = folder / "dataset.yaml"
    spec_path.write_text(dump_yaml(doc, sort_keys=False, width=100))
    return [spec_path, *files]
