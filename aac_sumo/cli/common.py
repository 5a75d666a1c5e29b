"""What every ``aac-sumo`` command shares: the program name, the one-line usage error, the
parser that raises it, and the argument checks."""

from __future__ import annotations

import argparse
import difflib
import re
from pathlib import Path

PROG = "aac-sumo"


class UsageError(Exception):
    """A command-line mistake; its message is one line."""


class Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line instead of usage + message, still exit status 2
        where = self.prog[len(PROG):].strip()
        raise UsageError((f"{where}: {message}" if where else message) + _did_you_mean(message))


def _did_you_mean(message: str) -> str:
    """``; did you mean 'run'?`` for argparse's "invalid choice: 'rn' (choose from ...)", else nothing."""
    found = re.search(r"invalid choice: '?([^' ]*)'? \(choose from (.*)\)", message)
    if not found:
        return ""
    match = difflib.get_close_matches(found.group(1), [c.strip(" '") for c in found.group(2).split(",")], n=1)
    return f"; did you mean '{match[0]}'?" if match else ""


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value}")
    return value


def int_list(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected integers >= 1, got {text!r}")
    return values


def check_out(out: Path) -> None:
    """Fail before any work when ``--out`` exists but is not a directory."""
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: expected a directory, found a file")
