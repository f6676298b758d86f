"""sims/rng_grid.py: the stand's random numbers, made cheaply, are numpy's own word for word.

Truth: numpy's SeedSequence -> PCG64 -> Generator for the same (entropy, spawn key, g),
the way the stand made every block's generator before (and the way the coverage
campaigns' realisations were drawn).
"""

from __future__ import annotations

import numpy as np
import pytest

from sims.rng_grid import RngGrid, pcg64_state, seed_states
from sims.stand import RNG_BLOCK_SAMPLES, AxisTruth, SimulatedStand, StandTruth

#: block indices at the edges of the spawn key's word encoding, and ordinary ones
_BLOCKS = [0, 1, 2, 1023, 1024, 25_765, 2**31, 2**32 - 1, 2**32, 2**40 + 7, 2**63 + 5]


def _numpy(entropy: object, key: tuple[int, ...], g: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(entropy, spawn_key=(*key, g))


@pytest.mark.parametrize("entropy, key", [
    (1, (0,)), (0, ()), (2**32 - 1, (1, 2)), (2**64 + 3, (0, 1)),
    (339_452_381_772_950_198_409_046_214_776_285_364_123, (3,)),   # a 128-bit entropy
    ([7, 4], ()), ([2**40, 0, 5, 1, 9], (2, 0)),                    # pool-sized and longer
])
def test_seed_states_and_pcg64_states_are_numpys(entropy: object, key: tuple[int, ...]) -> None:
    got = seed_states(entropy, key, np.array(_BLOCKS, dtype=np.uint64))  # type: ignore[arg-type]
    for g, row in zip(_BLOCKS, got, strict=True):
        seq = _numpy(entropy, key, g)
        np.testing.assert_array_equal(row, seq.generate_state(4, np.uint64), err_msg=f"g={g}")
        assert pcg64_state(row) == np.random.PCG64(seq).state, f"g={g}"


def test_the_grids_normals_are_those_of_numpys_generator_per_block() -> None:
    seq = np.random.SeedSequence(20261127).spawn(3)[2]
    grid = RngGrid(seq)
    for stream, g, n in [(0, 0, 4096), (1, 5, 4096), (2, 5, 3), (1, 1025, 17), (0, 4, 1),
                         (1, 5, 4096)]:            # back to an earlier block: same numbers
        want = np.random.default_rng(_numpy(seq.entropy, (*seq.spawn_key, stream), g)
                                     ).standard_normal(n)
        np.testing.assert_array_equal(grid.normals(stream, g, n), want)


def test_a_stand_axis_draws_numpys_numbers_for_its_noise() -> None:
    """The stand's table-noise stream for block 3, against numpy's own construction."""
    stand = SimulatedStand(StandTruth(seed=5, axes={"outer": AxisTruth()}), {"outer": 1000.0})
    axis = stand.axes["outer"]
    per = RNG_BLOCK_SAMPLES
    k = 3
    g0 = k * axis.block_samples // per
    seq = axis._ss
    want = np.concatenate([
        np.random.default_rng(_numpy(seq.entropy, (*seq.spawn_key, 0), g0 + j)
                              ).standard_normal(per)
        for j in range(axis.block_samples // per)])
    np.testing.assert_array_equal(axis._normals("table", k), want)
