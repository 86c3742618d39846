"""The console side of a design study: a progress bar, and Optuna's log lines kept
quiet."""

from __future__ import annotations

import logging
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["Progress", "quiet_optuna"]


@contextmanager
def quiet_optuna() -> Iterator[None]:
    """Optuna's per-trial log lines off (the progress bar says enough)."""
    import optuna

    level = optuna.logging.get_verbosity()
    optuna.logging.set_verbosity(logging.WARNING)
    try:
        yield
    finally:
        optuna.logging.set_verbosity(level)


class Progress:
    """A progress bar on stderr: tqdm if importable, else a plain line per trial."""

    def __init__(self, total: int, enabled: bool) -> None:
        self._bar: Any = None
        self._enabled = enabled
        self._done = 0
        self._total = total
        if not enabled:
            return
        try:
            from tqdm import tqdm
        except ImportError:  # pragma: no cover - tqdm is a core dependency
            return
        self._bar = tqdm(total=total, desc="spm optimize", unit="trial", file=sys.stderr)

    def update(self, text: str) -> None:
        self._done += 1
        if self._bar is not None:
            self._bar.set_postfix_str(text, refresh=False)
            self._bar.update(1)
        elif self._enabled:
            print(f"trial {self._done}/{self._total}: {text}", file=sys.stderr)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
