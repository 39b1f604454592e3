"""The one cache type: values computed from inputs, keyed by the inputs' values.

Owns: :class:`Cache` and :func:`value_key`.  May import: numpy only.

Every memo in the package is a :class:`Cache`.  A key is built from the
*values* of the inputs (an array by its dtype, shape and bytes), never from an
object's identity: an object enters a key through its ``cache_key`` attribute
(a value that determines everything the cached result depends on) or, for
hashable value objects (frozen dataclasses compared by value, numbers,
strings), through its own hash.  Objects hashed by identity are refused, so an
``id()`` key cannot slip back in through an object.

One invalidation rule: entries are dropped least recently used first once
more than ``maxsize`` are held, and all at once by :meth:`Cache.clear`, which
the owner calls when the inputs the entries were built from stop being
relevant (a fit ends, a problem is dropped).
"""

from collections import OrderedDict
from collections.abc import Callable, Hashable
from enum import Enum
from typing import Any

import numpy as np

__all__ = ["Cache", "value_key"]


_PLAIN = frozenset({bool, int, float, complex, str, bytes, type(None)})


def _part(obj: Any) -> Hashable:
    kind = type(obj)
    if kind is np.ndarray:
        return ("ndarray", obj.dtype.str, obj.shape, obj.tobytes())
    if kind in _PLAIN:
        return obj
    if kind is tuple or kind is list:
        return (kind.__name__,) + tuple(map(_part, obj))
    if isinstance(obj, np.ndarray):
        return ("ndarray", obj.dtype.str, obj.shape, obj.tobytes())
    if obj is None or isinstance(obj, (bool, int, float, complex, str, bytes, Enum, np.generic)):
        return obj
    if isinstance(obj, (tuple, list)):
        return (type(obj).__name__,) + tuple(_part(o) for o in obj)
    if isinstance(obj, frozenset):
        return ("frozenset", frozenset(_part(o) for o in obj))
    key = getattr(obj, "cache_key", None)
    if key is not None:
        return (type(obj).__name__, _part(key))
    if type(obj).__hash__ is None or type(obj).__hash__ is object.__hash__:
        raise TypeError(f"{type(obj).__name__} cannot be part of a cache key: it is hashed by identity. "
                        f"Give it a 'cache_key' attribute (the values its results depend on).")
    return obj


def value_key(*parts: Any) -> Hashable:
    """A hashable key made of the values of ``parts``.

    Arrays enter by dtype, shape and bytes; tuples and lists element by
    element; an object with a ``cache_key`` by that value; other hashable
    value objects as themselves.

    >>> value_key(np.arange(3.0), "x") == value_key(np.arange(3.0), "x")
    True
    >>> value_key(np.arange(3.0)) == value_key(np.arange(3.0).astype(np.float32))
    False
    """
    return tuple(_part(p) for p in parts)


class Cache:
    """Computed values keyed by the values of their inputs (:func:`value_key`).

    Parameters
    ----------
    maxsize : int or None
        Entries kept; the least recently used is dropped past it (None: no
        bound, the owner clears).

    >>> cache = Cache(maxsize=2)
    >>> cache.get((np.ones(2),), lambda: "computed")
    'computed'
    >>> cache.get((np.ones(2),), lambda: "again")
    'computed'
    >>> len(cache), cache.hits, cache.misses
    (1, 1, 1)
    """

    def __init__(self, maxsize: int | None = None):
        if maxsize is not None and maxsize < 1:
            raise ValueError(f"The 'maxsize' parameter of Cache must be a positive int or None. Got {maxsize!r} instead.")
        self.maxsize = maxsize
        self._entries: OrderedDict = OrderedDict()
        self.hits = 0
        self.misses = 0

    def key(self, parts: tuple) -> Hashable:
        """The key of ``parts`` (precompute it when one key is looked up several times)."""
        return value_key(*parts)

    def get(self, parts: tuple, compute: Callable[[], Any], *, key: Hashable = None) -> Any:
        """The value stored under ``parts`` (or the precomputed ``key``), computed by ``compute()`` if absent."""
        k = value_key(*parts) if key is None else key
        found, value = self._find(k)
        if found:
            return value
        value = compute()
        self._store(k, value)
        return value

    def lookup(self, parts: tuple, *, key: Hashable = None) -> tuple[bool, Any]:
        """``(True, value)`` if ``parts`` (or ``key``) is held, else ``(False, None)``."""
        return self._find(value_key(*parts) if key is None else key)

    def _find(self, k: Hashable) -> tuple[bool, Any]:
        entries = self._entries
        try:
            value = entries[k]
        except KeyError:
            self.misses += 1
            return False, None
        self.hits += 1
        entries.move_to_end(k)
        return True, value

    def put(self, parts: tuple, value: Any, *, key: Hashable = None) -> None:
        """Store ``value`` under ``parts`` (or ``key``)."""
        self._store(value_key(*parts) if key is None else key, value)

    def _store(self, k: Hashable, value: Any) -> None:
        self._entries[k] = value
        self._entries.move_to_end(k)
        if self.maxsize is not None:
            while len(self._entries) > self.maxsize:
                self._entries.popitem(last=False)

    def clear(self) -> None:
        """Drop every entry (the one invalidation the owner performs)."""
        self._entries.clear()

    def __contains__(self, parts: tuple) -> bool:
        return value_key(*parts) in self._entries

    def __len__(self) -> int:
        return len(self._entries)
