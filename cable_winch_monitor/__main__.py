"""`cable-winch-monitor` and `python -m cable_winch_monitor`: the command line as a process of its own.

The process is started and ended with fewer garbage collections than Python's default: the imports make
some hundred thousand objects that all last, so the collections among them find nothing (9 ms of every
start); at exit the interpreter's last collection scanned everything the command made (30 ms after a
replay of recording (a)), which the operating system frees anyway. `cli.main`, which tests call in their
own process, leaves the collector as it was.
"""
from __future__ import annotations

import gc
import sys
from typing import NoReturn


def run() -> NoReturn:
    collecting = gc.isenabled()
    gc.disable()
    from .cli import main
    if collecting:
        gc.enable()
    status = main()
    gc.freeze()
    sys.exit(status)


if __name__ == "__main__":
    run()
