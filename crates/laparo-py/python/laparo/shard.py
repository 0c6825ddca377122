"""Sharding of dataset jobs: shard ``I/N`` takes the items at positions ``i`` with
``i % N == I``, exactly like the CLI's ``--shard I/N``; N processes (Slurm array tasks,
Ray/Dask tasks) with shards 0..N-1 together cover every item once."""
from __future__ import annotations

from typing import Optional, Sequence, Tuple, TypeVar, Union

T = TypeVar("T")
ShardLike = Union[None, str, Tuple[int, int]]


def parse(shard: ShardLike) -> Tuple[int, int]:
    """``None`` → (0, 1); ``"I/N"`` or ``(I, N)`` → (I, N), checked (0 <= I < N)."""
    if shard is None:
        return (0, 1)
    if isinstance(shard, str):
        try:
            i_s, n_s = shard.split("/")
            i, n = int(i_s), int(n_s)
        except ValueError:
            raise ValueError(f"shard: '{shard}' (expected 'I/N', e.g. '0/3')") from None
    else:
        try:
            i, n = (int(v) for v in shard)
        except (TypeError, ValueError):
            raise TypeError(f"shard: expected 'I/N' or (I, N), got {shard!r}") from None
    if not (n >= 1 and 0 <= i < n):
        raise ValueError(f"shard: {i}/{n} (need 0 <= I < N)")
    return (i, n)


def indices(n_items: int, shard: ShardLike) -> list:
    """Positions 0..n_items-1 that belong to ``shard``."""
    i, n = parse(shard)
    return list(range(i, n_items, n))


def select(items: Sequence[T], shard: ShardLike) -> list:
    """The items of ``shard``, in order."""
    return [items[k] for k in indices(len(items), shard)]
