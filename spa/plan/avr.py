"""The player's size on an ATmega328P (32 KB flash, 2 KB RAM), where avr-gcc is installed:
the header compiled with a stand-in for the sketch's loop (the tick, every run), and the
sketch itself compiled as C++ against declarations of the Arduino API, measured with
avr-size (the Arduino core's own code, about 3 KB, is not counted)."""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

__all__ = ["ARDUINO_STUB", "ATMEGA328P", "avr_size", "sketch_size"]

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


#: Declarations of the Arduino API the sketch calls (the core provides their code), so that
#: the sketch compiles as C++ for the board without the Arduino core installed.
ARDUINO_STUB = r"""/* A stand-in for the Arduino API the player's sketch uses: declarations
 * only (the core provides the code), so that the sketch compiles for the board. */
#ifndef ARDUINO_STUB_H
#define ARDUINO_STUB_H
#include <stdint.h>
#define HIGH 1
#define LOW 0
#define OUTPUT 1
#define A0 14
#define HEX 16
extern "C" {
void pinMode(uint8_t pin, uint8_t mode);
void digitalWrite(uint8_t pin, uint8_t value);
int analogRead(uint8_t pin);
unsigned long micros(void);
}
struct StubSerial {
  void begin(unsigned long baud);
  int availableForWrite(void);
  operator bool() { return true; }
  void print(const char *s);
  void print(char c);
  void print(long v, int base = 10);
  void print(int v, int base = 10);
  void println(const char *s);
  void println(long v, int base = 10);
  void println(int v, int base = 10);
};
extern StubSerial Serial;
#endif
"""


def _size(size: str, obj: Path) -> dict[str, int]:
    out = subprocess.run([size, str(obj)], capture_output=True, text=True, check=True).stdout
    text, data, bss = (int(v) for v in re.split(r"\s+", out.splitlines()[1].strip())[:3])
    return {"flash": text + data, "ram": data + bss}


def sketch_size(folder: str | Path, mcu: str = "atmega328p") -> dict[str, int] | None:
    """Flash and static RAM of a plan folder's ``player.ino`` compiled as C++ for ``mcu``
    (``-Wall -Wextra -Werror``) against :data:`ARDUINO_STUB`, bytes, the core's own code not
    counted; None when avr-g++ or avr-size is not installed.

    Raises
    ------
    RuntimeError
        If the sketch does not compile.
    """
    gxx, size = shutil.which("avr-g++"), shutil.which("avr-size")
    if gxx is None or size is None:
        return None
    player = Path(folder) / "player"
    with tempfile.TemporaryDirectory(prefix="spa-ino-") as tmp:
        (Path(tmp) / "Arduino.h").write_text(ARDUINO_STUB, encoding="utf-8")
        src, obj = Path(tmp) / "sketch.cpp", Path(tmp) / "sketch.o"
        src.write_text('#include "Arduino.h"\n#include "player.ino"\n', encoding="utf-8")
        cmd = [gxx, f"-mmcu={mcu}", "-Os", "-std=c++11", "-Wall", "-Wextra", "-Werror",
               f"-I{tmp}", f"-I{player}", "-c", str(src), "-o", str(obj)]  # fmt: skip
        res = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if res.returncode != 0:
            raise RuntimeError(f"the sketch does not build for {mcu}:\n{res.stderr}")
        return _size(size, obj)


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
        return _size(size, elf)
