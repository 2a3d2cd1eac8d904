"""Memory-mapped ``.npy`` files written atomically: the caches of the reader and of aggregates."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.utils import atomic_path


class AtomicNpys:
    """Memory-mapped .npy files opened under unique temporary names (``atomic_path``), renamed into place
    on success and removed on failure, so two processes building the same cache never share a file."""

    def __init__(self, folder: Path, specs: dict[str, tuple[tuple[int, ...], Any]]) -> None:
        self.folder = folder
        self.specs = specs
        self.stack = ExitStack()
        self.maps: dict[str, np.memmap] = {}

    def __enter__(self) -> dict[str, np.memmap]:
        try:
            for name, (shape, dtype) in self.specs.items():
                tmp = self.stack.enter_context(atomic_path(self.folder / f"{name}.npy"))
                self.maps[name] = np.lib.format.open_memmap(tmp, mode="w+", dtype=dtype, shape=shape)
        except BaseException as exc:
            self.maps.clear()
            self.stack.__exit__(type(exc), exc, exc.__traceback__)  # with an exception: delete, not rename
            raise
        return self.maps

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        for m in self.maps.values():
            m.flush()
        self.maps.clear()  # unmapped before the rename
        self.stack.__exit__(exc_type, exc, tb)
