"""The progress bar of a long run (tqdm)."""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["progress_bar", "PROGRESS_MIN_STEPS"]

#: runs of at least this many steps show a bar by default (on a terminal)
PROGRESS_MIN_STEPS = 20_000


def progress_bar(progress: bool | dict[str, Any] | None, n_steps: int, desc: str) -> Any:
    show = bool(progress) if progress is not None else (n_steps >= PROGRESS_MIN_STEPS and sys.stderr.isatty())
    if not show:
        return None
    from tqdm.auto import tqdm

    bar_kw: dict[str, Any] = {"unit": "step", "desc": desc, "mininterval": 0.5, "leave": False}
    if isinstance(progress, dict):
        bar_kw.update(progress)
    return tqdm(total=n_steps, **bar_kw)
