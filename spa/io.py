"""Small, deterministic writers and logging shared by the workflow scripts."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import pandas as pd

__all__ = ["get_logger", "save_figure", "write_csv"]


def get_logger(name: str, log_path: str | Path | None = None) -> logging.Logger:
    """Return a logger writing to ``log_path`` (and stderr), for progress of a workflow script."""
    logger = logging.getLogger(f"spa.{name}")
    logger.setLevel(logging.INFO)
    logger.handlers.clear()
    fmt = logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s")
    handlers: list[logging.Handler] = [logging.StreamHandler()]
    if log_path is not None:
        Path(log_path).parent.mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(log_path, mode="w"))
    for h in handlers:
        h.setFormatter(fmt)
        logger.addHandler(h)
    return logger


def write_csv(df: pd.DataFrame, path: str | Path) -> None:
    """Write a table as CSV with full float precision and no index (byte-stable)."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(path, index=False, float_format="%.10g", lineterminator="\n")


def save_figure(fig: Any, path: str | Path, dpi: int = 120) -> None:
    """Save a matplotlib figure as PNG without time stamps or version strings (byte-stable)."""
    import matplotlib.pyplot as plt

    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, metadata={"Software": None})
    plt.close(fig)
