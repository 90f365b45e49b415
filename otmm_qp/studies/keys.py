"""Short episode ids: the first :data:`ID_LENGTH` hex digits of an episode's key.

Every episode row carries ``episode_id``; the key is the SHA-256 of the episode's full spec,
so the id is stable across runs and executors.
"""

from __future__ import annotations

#: Hex digits of ``episode_key`` in an episode id (40 bits: a collision among 10⁵ episodes
#: has probability ≈ 5·10⁻³; ``find_episode`` then asks for more digits).
ID_LENGTH = 10
#: Fewest hex digits ``find_episode`` accepts.
MIN_ID_LENGTH = 6


def episode_id(key: str) -> str:
    """The short id of an episode: the first :data:`ID_LENGTH` characters of its key."""
    return str(key)[:ID_LENGTH]
