"""The motion queue (thesis 5.2, Figure 5.1): requests from the planning level, served by the trajectory level.

A plain FIFO shared by two threads. The planning level ``put``s requests and never blocks;
the trajectory generator ``get``s one when it nears the end of its current segment, and
finds ``None`` when the queue is empty (then it repeats the last request: the arm holds).
"""
from __future__ import annotations

import collections
import threading
from typing import Generic, TypeVar

T = TypeVar("T")


class MotionQueue(Generic[T]):
    """Thread-safe FIFO of motion requests."""

    def __init__(self) -> None:
        self._items: collections.deque[T] = collections.deque()
        self._lock = threading.Lock()

    def put(self, item: T) -> None:
        with self._lock:
            self._items.append(item)

    def push_front(self, item: T) -> None:
        """Put a request back at the head (the generator defers one it will start from rest)."""
        with self._lock:
            self._items.appendleft(item)

    def get(self) -> T | None:
        """The oldest request, or None if the queue is empty (never blocks: it runs at the control level)."""
        with self._lock:
            return self._items.popleft() if self._items else None

    def peek(self) -> T | None:
        with self._lock:
            return self._items[0] if self._items else None

    def clear(self) -> list[T]:
        """Remove and return every queued request (used when a fault stops the arm)."""
        with self._lock:
            items = list(self._items)
            self._items.clear()
            return items

    def __len__(self) -> int:
        return len(self._items)
