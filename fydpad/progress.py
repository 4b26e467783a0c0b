"""A progress bar on a terminal, silence otherwise."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

from tqdm import tqdm

T = TypeVar("T")


def progress(items: Iterable[T], total: int | None = None, desc: str = "",
             unit: str = "frame") -> Iterator[T]:
    """Wrap ``items`` in a tqdm bar on stderr when stderr is a terminal."""
    yield from tqdm(
        items, total=total, desc=desc, unit=unit, disable=not sys.stderr.isatty(),
        leave=False, dynamic_ncols=True,
    )
