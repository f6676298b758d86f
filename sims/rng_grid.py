"""The stand's random-number grid: the generator of (seed, stream, block g), made cheaply.

The stand draws the random numbers of samples g*4096 onward from the generator numpy
makes of `SeedSequence(entropy, spawn_key=(*axis_key, stream, g))` (a counter-based
scheme: any block's numbers without the blocks before it, so where a clock step falls
never changes a number). numpy's way costs a SeedSequence, a PCG64 and a Generator for
every block: ~30 us, a third of the normals' cost on the paper ladder (~100 k blocks).

Here the same numbers, word for word:
- the SeedSequence's hash (numpy's `bit_generator.pyx`: `mix_entropy` over the entropy
  and the spawn key as 32-bit words, pool of 4; then `generate_state(4, uint64)`) is
  computed for 1024 consecutive blocks at once in numpy's uint32 arithmetic;
- PCG64's seeding (`pcg64_set_seed`: state 0, inc = 2 initseq + 1, a step, state +=
  initstate, a step; the 128-bit LCG's default multiplier) is done in Python integers,
  and the state set on one bit generator the stream keeps.
tests/test_rng_grid.py holds both to numpy's own for edge-case keys and indices.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Sequence

import numpy as np

_M32 = 0xFFFFFFFF
_M128 = (1 << 128) - 1
# SeedSequence's hash constants (numpy/random/bit_generator.pyx)
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = 0xCA01F9DD, 0x4973F715
_POOL = 4
_XSHIFT = np.uint32(16)
# PCG's 128-bit LCG multiplier (pcg64.h PCG_DEFAULT_MULTIPLIER_128)
_PCG_MULT = (2549297995355413924 << 64) + 4865540595714422341
#: blocks whose seeds are hashed together (and kept) per stream
_SEED_CHUNK = 1024


def _words(n: int) -> list[int]:
    """An int as SeedSequence reads it: 32-bit words, least significant first."""
    if n < 0:
        raise ValueError(f"seed words must be >= 0, got {n}")
    out = []
    while True:
        out.append(n & _M32)
        n >>= 32
        if not n:
            return out


def _as_words(x: int | Iterable[int]) -> list[int]:
    if isinstance(x, int | np.integer):
        return _words(int(x))
    return [w for v in x for w in _words(int(v))]


def seed_states(entropy: int | Iterable[int], spawn_key: Iterable[int],
                blocks: np.ndarray) -> np.ndarray:
    """(len(blocks), 4) uint64: `SeedSequence(entropy, spawn_key=(*spawn_key, g))
    .generate_state(4, np.uint64)` for every g in `blocks`."""
    g = np.asarray(blocks, dtype=np.uint64).reshape(-1)
    run = _as_words(entropy)
    run += [0] * max(_POOL - len(run), 0)      # padded to the pool when a key follows
    head = run + _as_words(spawn_key)
    out = np.empty((g.size, 4), dtype=np.uint64)
    lo = (g & np.uint64(_M32)).astype(np.uint32)
    hi = (g >> np.uint64(32)).astype(np.uint32)
    big = hi != 0                               # g >= 2**32 is two words of the key
    for sel, tail in ((~big, (lo,)), (big, (lo, hi))):
        if sel.any():
            m = int(sel.sum())
            cols = [np.full(m, w, dtype=np.uint32) for w in head] + [t[sel] for t in tail]
            out[sel] = _hash(cols)
    return out


def _hash(entropy: list[np.ndarray]) -> np.ndarray:
    """SeedSequence's mix_entropy and generate_state(4, uint64), one row per column entry."""
    u32 = np.uint32
    hash_const = [u32(_INIT_A)]

    def hashmix(v: np.ndarray) -> np.ndarray:
        v = v ^ hash_const[0]
        hash_const[0] = u32((int(hash_const[0]) * _MULT_A) & _M32)
        v = v * hash_const[0]
        return v ^ (v >> _XSHIFT)

    def mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        r: np.ndarray = u32(_MIX_MULT_L) * x - u32(_MIX_MULT_R) * y
        mixed: np.ndarray = r ^ (r >> _XSHIFT)
        return mixed

    m = entropy[0].size
    with np.errstate(over="ignore"):   # uint32 arithmetic wraps, as in C
        mixer = [hashmix(entropy[i] if i < len(entropy) else np.zeros(m, u32))
                 for i in range(_POOL)]
        for src in range(_POOL):
            for dst in range(_POOL):
                if src != dst:
                    mixer[dst] = mix(mixer[dst], hashmix(mixer[src]))
        for src in range(_POOL, len(entropy)):
            for dst in range(_POOL):
                mixer[dst] = mix(mixer[dst], hashmix(entropy[src]))
        hash_b = _INIT_B
        words = []
        for i in range(8):                      # 4 uint64 = 8 uint32, low word first
            v = mixer[i % _POOL] ^ u32(hash_b)
            hash_b = (hash_b * _MULT_B) & _M32
            v = v * u32(hash_b)
            words.append(v ^ (v >> _XSHIFT))
    return np.stack(words, axis=1).astype("<u4").view("<u8").reshape(m, 4)


def pcg64_state(seed: np.ndarray) -> dict[str, str | int | dict[str, int]]:
    """The `PCG64.state` that `PCG64(seed sequence)` sets from its 4 words."""
    initstate = (int(seed[0]) << 64) | int(seed[1])
    initseq = (int(seed[2]) << 64) | int(seed[3])
    inc = ((initseq << 1) | 1) & _M128
    state = (inc + initstate) & _M128           # a step from 0 is inc
    state = (state * _PCG_MULT + inc) & _M128
    return {"bit_generator": "PCG64", "state": {"state": state, "inc": inc},
            "has_uint32": 0, "uinteger": 0}


class RngGrid:
    """The generators of one axis's streams, block by block (thread-safe)."""

    def __init__(self, seq: np.random.SeedSequence) -> None:
        assert seq.entropy is not None  # a SeedSequence always has its entropy once made
        self._entropy: int | Sequence[int] = seq.entropy
        self._key = tuple(int(k) for k in seq.spawn_key)
        self._lock = threading.Lock()
        self._seeds: dict[tuple[int, int], np.ndarray] = {}
        self._bits = np.random.PCG64(0)
        self._gen = np.random.Generator(self._bits)

    def _seed(self, stream: int, g: int) -> np.ndarray:
        c = g // _SEED_CHUNK
        chunk = self._seeds.get((stream, c))
        if chunk is None:
            if len(self._seeds) >= 8:           # streams move forward: keep a few chunks
                self._seeds.pop(next(iter(self._seeds)))
            chunk = seed_states(self._entropy, (*self._key, stream),
                                np.arange(c * _SEED_CHUNK, (c + 1) * _SEED_CHUNK))
            self._seeds[(stream, c)] = chunk
        state: np.ndarray = chunk[g - c * _SEED_CHUNK]
        return state

    def normals(self, stream: int, g: int, n: int) -> np.ndarray:
        """The first `n` standard normals of block g's generator in `stream`."""
        with self._lock:
            # (numpy types the setter as a private TypedDict; the dict is its shape)
            self._bits.state = pcg64_state(self._seed(stream, g))  # type: ignore[assignment]
            return self._gen.standard_normal(n)
