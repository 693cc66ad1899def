"""Integrals kept by a digest of what they are taken from.

A run's frames often meet the same surfaces again (a ball pressed by a moving plate, a
ball on a block under it): their contact integrals are kept by a digest of the arrays
they depend on and taken once. A :class:`Kept` store holds the last few, under a lock (a
sweep's threads may share the module).
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Kept", "digest"]

T = TypeVar("T")


def digest(*parts: ArrayLike | Mapping[str, ArrayLike]) -> bytes:
    """A digest of arrays (shape, type and bytes) and of mappings of names to arrays."""
    h = hashlib.blake2b(digest_size=20)
    for part in parts:
        items = sorted(part.items()) if isinstance(part, Mapping) else [("", part)]
        for name, value in items:
            a = np.ascontiguousarray(value)
            h.update(f"{name}|{a.dtype}|{a.shape}|".encode())
            h.update(a.tobytes())
    return h.digest()


class Kept(Generic[T]):
    """The last ``size`` values made, by key; the least recently asked go first."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._values: OrderedDict[bytes, T] = OrderedDict()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._values)

    def clear(self) -> None:
        """Forget every value."""
        with self._lock:
            self._values.clear()

    def get(self, key: bytes, make: Callable[[], T]) -> T:
        """The value kept for ``key``, or ``make()``'s, kept from now on."""
        with self._lock:
            value = self._values.get(key)
        if value is None:
            value = make()
        with self._lock:
            self._values[key] = value
            self._values.move_to_end(key)
            while len(self._values) > self.size:
                self._values.popitem(last=False)
        return value
