"""The player's size on an ATmega328P (32 KB flash, 2 KB RAM), where avr-gcc is installed:
the header compiled with a stand-in for the sketch's loop (the tick, every run), measured
with avr-size."""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

__all__ = ["ATMEGA328P", "avr_size"]

#: Flash and RAM of an ATmega328P, bytes.
ATMEGA328P = {"flash": 32768, "ram": 2048}

_MAIN = r"""#include "player.h"
volatile long adc_in;
volatile long sink;
int main(void)
{
    spa_plan_state s;
    int run, valve, log, last;
    long q;
    for (run = 0; run < SPA_PLAN_N_RUNS; ++run) {
        spa_plan_start(&s, run);
        do {
            last = spa_plan_tick(&s, adc_in, &valve, &q, &log);
            sink = valve + q + log;
        } while (!last);
    }
    return 0;
}
"""


def avr_size(folder: str | Path, mcu: str = "atmega328p") -> dict[str, int] | None:
    """Flash (text + data) and RAM (data + bss) of a plan folder's player on ``mcu``, bytes;
    None when avr-gcc or avr-size is not installed.

    Raises
    ------
    RuntimeError
        If the player does not compile for the board.
    """
    gcc, size = shutil.which("avr-gcc"), shutil.which("avr-size")
    if gcc is None or size is None:
        return None
    player = Path(folder) / "player"
    with tempfile.TemporaryDirectory(prefix="spa-avr-") as tmp:
        src, elf = Path(tmp) / "main.c", Path(tmp) / "main.elf"
        src.write_text(_MAIN, encoding="utf-8")
        cmd = [gcc, f"-mmcu={mcu}", "-Os", "-std=c99", "-Wall", "-Wextra", "-pedantic",
               "-Werror", f"-I{player}", str(src), "-o", str(elf), "-lm"]  # fmt: skip
        res = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if res.returncode != 0:
            raise RuntimeError(f"the player does not build for {mcu}:\n{res.stderr}")
        out = subprocess.run([size, str(elf)], capture_output=True, text=True, check=True).stdout
    text, data, bss = (int(v) for v in re.split(r"\s+", out.splitlines()[1].strip())[:3])
    return {"flash": text + data, "ram": data + bss}
