"""The FOG frame decoder against frames built by hand from the KVH manual's layout.

Reference frames here come from `struct` and a bit-at-a-time CRC written from the
CRC parameters (not from the code under test), so a wrong table, byte order or field
offset in the decoder fails these tests.
"""

from __future__ import annotations

import random
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivers.fog_formats import (
    CRC32_MPEG2,
    FORMATS,
    KVH_A,
    DecodeState,
    StreamDecoder,
    decode,
    get_format,
)


def crc32_mpeg2_bitwise(data: bytes) -> int:
    """CRC-32/MPEG-2 one bit at a time: poly 0x04C11DB7, init all ones, no reflection."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc ^= byte << 24
        for _ in range(8):
            crc = ((crc << 1) ^ 0x04C11DB7) & 0xFFFFFFFF if crc & 0x80000000 \
                else (crc << 1) & 0xFFFFFFFF
    return crc


def kvh_a(seq: int, x: float = 0.0, y: float = 0.0, z: float = 0.0, *,
          status: int = 0x77, temp: int = 25, accel: tuple[float, float, float] = (0, 0, 0)
          ) -> bytes:
    """Format A as tables 5-1/5-2 of the KVH 1775 manual: 36 bytes, big-endian."""
    body = b"\xfe\x81\xff\x55" + struct.pack(">3f3fBBh", x, y, z, *accel, status, seq % 128,
                                             temp)
    assert len(body) == 32
    return body + struct.pack(">I", crc32_mpeg2_bitwise(body))


def kvh_b(seq: int, z: float, timestamp_us: int) -> bytes:
    """Format B (tables 5-3/5-4): format A with a uint32 timestamp before the status."""
    body = b"\xfe\x81\xff\x56" + struct.pack(">3f3fIBBh", 0.0, 0.0, z, 0, 0, 1.0,
                                             timestamp_us, 0x77, seq % 128, 31)
    return body + struct.pack(">I", crc32_mpeg2_bitwise(body))


def stream(seqs: range | list[int], z0: float = 1.0) -> bytes:
    return b"".join(kvh_a(s, z=z0 + 0.25 * s) for s in seqs)


# -- CRC ---------------------------------------------------------------------------------

def test_crc_catalogue_check_value() -> None:
    # the CRC catalogue's check value of CRC-32/MPEG-2 over "123456789"
    assert CRC32_MPEG2.compute(b"123456789") == 0x0376E6E7
    assert crc32_mpeg2_bitwise(b"123456789") == 0x0376E6E7


@pytest.mark.parametrize("length", [1, 2, 7, 32, 36])
def test_vectorised_crc_equals_bitwise(length: int) -> None:
    rows = np.random.default_rng(length).integers(0, 256, (50, length), dtype=np.uint8)
    got = CRC32_MPEG2.compute_rows(rows)
    assert [int(c) for c in got] == [crc32_mpeg2_bitwise(r.tobytes()) for r in rows]


# -- single frames -------------------------------------------------------------------------

def test_decodes_hand_built_frame_fields() -> None:
    raw = kvh_a(5, 1.5, -2.25, 1e-3, status=0x75, temp=-12, accel=(0.5, -0.25, 1.0))
    frames, leftover, stats = decode(raw, "kvh-a")
    assert (stats.frames, stats.crc_errors, stats.gaps, leftover) == (1, 0, 0, b"")
    assert frames.index.tolist() == [0]
    assert frames.sequence.tolist() == [5]
    assert frames.status.tolist() == [0x75]
    assert frames.rates.tolist() == [[1.5, -2.25, np.float32(1e-3)]]
    assert frames.temperature.tolist() == [-12]
    assert [frames.extra[k][0] for k in ("ax", "ay", "az")] == [0.5, -0.25, 1.0]


def test_kvh_b_frame() -> None:
    raw = kvh_b(3, 0.125, 123456789) + kvh_b(4, 0.5, 123457789)
    frames, _, stats = decode(raw, "kvh-b")
    assert stats.frames == 2 and stats.crc_errors == 0
    assert frames.rates[:, 2].tolist() == [0.125, 0.5]
    assert frames.extra["timestamp_us"].tolist() == [123456789, 123457789]
    assert frames.extra["az"].tolist() == [1.0, 1.0]
    assert frames.temperature.tolist() == [31, 31]


def test_format_registry() -> None:
    assert {"kvh-a", "kvh-b"} <= set(FORMATS)
    assert KVH_A.size == 36 and FORMATS["kvh-b"].size == 40
    with pytest.raises(ValueError, match="unknown FOG frame format 'nope'"):
        get_format("nope")


def test_encoder_matches_manual_layout() -> None:
    rows = KVH_A.encode(np.array([7]), np.array([[1.5, -2.25, 1e-3]]), temperature=-12)
    assert rows.tobytes() == kvh_a(7, 1.5, -2.25, 1e-3, temp=-12)


# -- errors ---------------------------------------------------------------------------------

def test_corrupted_frame_is_rejected_and_counted() -> None:
    good = [kvh_a(s, z=float(s)) for s in range(6)]
    broken = bytearray(good[2])
    broken[14] ^= 0x01                      # one bit in the z rate
    raw = b"".join(good[:2]) + bytes(broken) + b"".join(good[3:])
    frames, _, stats = decode(raw, "kvh-a")
    assert frames.sequence.tolist() == [0, 1, 3, 4, 5]
    assert frames.index.tolist() == [0, 1, 3, 4, 5]
    assert (stats.crc_errors, stats.gaps, stats.lost_frames) == (1, 1, 1)
    assert stats.crc_error_offsets.tolist() == [72]
    assert stats.crc_error_index.tolist() == [2]
    assert 2.0 not in frames.rates[:, 2]


def test_broken_header_is_a_gap_not_a_crc_error() -> None:
    good = [kvh_a(s) for s in range(4)]
    raw = good[0] + b"\x00" + good[1][1:] + good[2] + good[3]
    frames, _, stats = decode(raw, "kvh-a")
    assert frames.index.tolist() == [0, 2, 3]
    assert (stats.crc_errors, stats.gaps, stats.skipped_bytes) == (0, 1, 36)


def test_gap_across_the_counter_wrap() -> None:
    seqs = list(range(120, 125)) + list(range(130, 140))   # 125..129 lost: 124 -> 2
    frames, _, stats = decode(stream(seqs), "kvh-a")
    assert frames.sequence.tolist()[4:6] == [124, 2]
    assert frames.index.tolist() == [s - 120 for s in seqs]
    assert stats.gap_index.tolist() == [5] and stats.gap_count.tolist() == [5]


def test_clean_wrap_is_no_gap() -> None:
    frames, _, stats = decode(stream(range(100, 400)), "kvh-a")
    assert stats.gaps == 0 and frames.index.tolist() == list(range(300))


def test_repeated_counter_reads_as_a_whole_wrap_lost() -> None:
    frames, _, stats = decode(kvh_a(9) + kvh_a(9), "kvh-a")
    assert frames.index.tolist() == [0, 128]
    assert stats.gap_count.tolist() == [127]


def test_garbage_then_sync_within_one_frame() -> None:
    rng = random.Random(4)
    junk = bytes(rng.randrange(256) for _ in range(333))
    decoys = b"\xfe\x81\xff\x55" + junk[:20] + b"\xfe\x81\xff" + b"\xfe\x81\xff\x55" + junk[:7]
    raw = stream(range(3)) + junk + decoys + stream(range(3, 8))
    frames, _, stats = decode(raw, "kvh-a")
    assert frames.sequence.tolist() == list(range(8))   # the first frame after is kept
    assert stats.gaps == 0
    assert stats.skipped_bytes == len(junk) + len(decoys)


def test_truncated_frame_waits_as_leftover_and_continues() -> None:
    raw = stream(range(4))
    frames, leftover, stats = decode(raw[:100], "kvh-a")
    assert frames.sequence.tolist() == [0, 1] and leftover == raw[72:100]
    assert stats.state.offset == 72
    frames2, leftover2, stats2 = decode(leftover + raw[100:], "kvh-a", stats.state)
    assert frames2.index.tolist() == [2, 3] and leftover2 == b""
    assert frames2.offset.tolist() == [72, 108]


def test_header_prefix_at_the_end_is_kept() -> None:
    _, leftover, stats = decode(b"\x01\x02\x03\xfe\x81", "kvh-a")
    assert leftover == b"\xfe\x81" and stats.skipped_bytes == 3


def forge_crc(frame: bytearray, free_at: int, target: int) -> None:
    """Set frame[free_at:free_at+4] so that crc(frame[:32]) == target (GF(2) solve)."""
    def crc_with(v: int) -> int:
        frame[free_at:free_at + 4] = v.to_bytes(4, "big")
        return crc32_mpeg2_bitwise(bytes(frame[:32]))
    base = crc_with(0)
    rows = [(crc_with(1 << i) ^ base, 1 << i) for i in range(32)]  # (image, preimage)
    want, pre = target ^ base, 0
    for bit in range(31, -1, -1):  # Gaussian elimination on the images' bits
        pivot = next((r for r in rows if r[0] >> bit & 1), None)
        if pivot is None:
            continue
        rows = [(a ^ pivot[0], b ^ pivot[1]) if a >> bit & 1 and (a, b) != pivot else (a, b)
                for a, b in rows if (a, b) != pivot]
        if want >> bit & 1:
            want, pre = want ^ pivot[0], pre ^ pivot[1]
    assert want == 0
    assert crc_with(pre) == target


def test_overlapping_valid_frames_keep_the_first() -> None:
    """Two CRC-valid frames that overlap cannot both be samples: the first one wins."""
    b = kvh_a(9, z=3.0)
    a = bytearray(36)
    a[0:4] = b"\xfe\x81\xff\x55"
    a[10:32] = b[0:22]                      # b's header starts 10 bytes into a
    forge_crc(a, 6, int.from_bytes(b[22:26], "big"))
    a[32:36] = b[22:26]
    raw = kvh_a(7) + bytes(a) + b[26:] + kvh_a(10)
    assert raw[36 + 10:36 + 46] == b        # both a and b are valid frames in raw
    frames, _, stats = decode(raw, "kvh-a")
    assert frames.offset.tolist() == [0, 36, 82]
    assert frames.sequence.tolist() == [7, int(a[29]), 10]
    assert stats.crc_errors == 0 and stats.skipped_bytes == 10


def test_empty_and_tiny_inputs() -> None:
    for raw in (b"", b"\xfe", b"\xfe\x81\xff\x55"):
        frames, leftover, stats = decode(raw, "kvh-a")
        assert len(frames) == 0 and leftover == raw and stats.bytes == 0


def test_stream_decoder_events_are_capped_but_counts_exact() -> None:
    dec = StreamDecoder("kvh-a", max_events=3)
    dec.feed(b"".join(kvh_a(s) for s in range(0, 400, 2)))   # 199 gaps of one frame
    assert dec.gaps == 199 and dec.lost_frames == 199
    assert dec.gap_events == [(1, 1), (3, 1), (5, 1)]


# -- properties -------------------------------------------------------------------------------

segment = st.one_of(
    st.tuples(st.just("frames"), st.integers(1, 6), st.integers(1, 3)),   # count, seq step
    st.tuples(st.just("junk"), st.binary(max_size=120)),
    st.tuples(st.just("decoy"), st.binary(max_size=40)),                  # header + noise
)


def build(segments: list[tuple]) -> tuple[bytes, list[int]]:
    """A stream and the sequence numbers of the intact frames in it, in order."""
    out, seqs, seq = [], [], 0
    for seg in segments:
        if seg[0] == "frames":
            for _ in range(seg[1]):
                out.append(kvh_a(seq, z=float(seq)))
                seqs.append(seq)
                seq += seg[2]
        elif seg[0] == "junk":
            out.append(seg[1])
        else:
            out.append(b"\xfe\x81\xff\x55" + seg[1])
    return b"".join(out), seqs


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=2000), st.lists(st.integers(1, 300), max_size=8))
def test_arbitrary_bytes_never_raise_and_stay_bounded(raw: bytes, cuts: list[int]) -> None:
    dec = StreamDecoder("kvh-a")
    pos = 0
    for c in [*cuts, len(raw)]:
        frames = dec.feed(raw[pos:pos + c])
        pos += c
        assert len(dec.leftover) < KVH_A.size              # memory: never more than a frame
        assert np.all(np.diff(frames.index) > 0)
    assert dec.bytes == len(raw)
    consumed = len(raw) - len(dec.leftover)
    assert dec.frames * KVH_A.size + dec.skipped_bytes == consumed


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(segment, min_size=1, max_size=12), st.lists(st.integers(1, 200), max_size=10))
def test_sync_is_never_lost_for_good(segments: list[tuple], cuts: list[int]) -> None:
    """Whatever garbage comes between them, every intact frame is decoded, in any chunking."""
    raw, seqs = build(segments)
    whole, leftover, whole_stats = decode(raw, "kvh-a")
    assert [s % 128 for s in seqs] == whole.sequence.tolist()
    dec = StreamDecoder("kvh-a")
    got, pos = [], 0
    for c in [*cuts, len(raw)]:
        got.append(dec.feed(raw[pos:pos + c]))
        pos += c
    assert np.concatenate([g.index for g in got]).tolist() == whole.index.tolist()
    assert np.concatenate([g.offset for g in got]).tolist() == whole.offset.tolist()
    assert dec.leftover == leftover
    assert dec.crc_events == list(zip(whole_stats.crc_error_index.tolist(),
                                      whole_stats.crc_error_offsets.tolist(), strict=True))
    assert (dec.skipped_bytes, dec.gaps) == (whole_stats.skipped_bytes, whole_stats.gaps)
    if seqs:  # index follows the counter: steps of 1..3 frames
        steps = np.diff(seqs)
        assert np.diff(whole.index).tolist() == steps.tolist()


def test_decode_state_default_is_stream_start() -> None:
    assert DecodeState() == DecodeState(offset=0, last_index=-1, last_sequence=None)
    assert DecodeState.starting_at(None) == DecodeState()


@pytest.mark.parametrize("first_index", [1_000_003 - 63, 1_000_002, 1_000_003, 1_000_003 + 64])
def test_a_capture_placed_by_the_clock_takes_the_index_its_counter_allows(
        first_index: int) -> None:
    """A FOG opened at clock t (drivers/fog.py): the first frame is the sample nearest
    first_index = ceil(t * rate) whose number the counter shows (n mod 128 = seq), by
    hand: sample 1 000 003 has seq 1 000 003 mod 128 = 67. Within half a wrap (64) of
    it the index is exact, the jump from first_index is no gap, later frames follow."""
    n0 = 1_000_003
    seqs = [n0, n0 + 1, n0 + 2, n0 + 5, n0 + 6]            # n0+3, n0+4 lost
    frames, _, stats = decode(stream(seqs), "kvh-a", DecodeState.starting_at(first_index))
    assert frames.sequence[0] == 67
    assert frames.index.tolist() == seqs
    assert stats.gap_index.tolist() == [n0 + 3] and stats.gap_count.tolist() == [2]
    assert stats.lost_frames == 2 and stats.state.first_index == first_index
    # fed in pieces, the stream decoder gives the same (the state carries on)
    dec = StreamDecoder("kvh-a")
    dec.state = DecodeState.starting_at(first_index)
    data = stream(seqs)
    got = np.concatenate([dec.feed(data[i:i + 50]).index for i in range(0, len(data), 50)])
    assert got.tolist() == seqs and dec.lost_frames == 2


def test_a_capture_placed_more_than_half_a_wrap_off_is_a_wrap_off() -> None:
    """The counter cannot tell more: 65 samples after first_index, the frame is taken
    for the one 128 earlier (what the 64 ms bound in drivers/fog.py says)."""
    frames, _, _ = decode(stream([1000]), "kvh-a", DecodeState.starting_at(1000 - 65))
    assert frames.index.tolist() == [1000 - 128]
    near_zero, _, _ = decode(stream([100]), "kvh-a", DecodeState.starting_at(0))
    assert near_zero.index.tolist() == [100]    # never before 0: a wrap later instead


def test_decode_command_exits_1_when_nothing_decodes(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Random bytes, or a kvh-a capture read as kvh-b: exit 1, naming the formats tried."""
    from bench.app.cli import main

    noise = tmp_path / "noise.bin"
    noise.write_bytes(np.random.default_rng(13).bytes(20_000))
    assert main(["decode", str(noise), "--format", "kvh-a"]) == 1
    err = capsys.readouterr().err
    assert "no frame of format kvh-a" in err and "formats tried: kvh-a, kvh-b" in err, err
    capture = tmp_path / "a.bin"
    capture.write_bytes(stream(range(50)))
    assert main(["decode", str(capture), "--format", "kvh-b"]) == 1
    err = capsys.readouterr().err
    assert "decode as kvh-a: 50 frame(s)" in err, err
    assert main(["decode", str(capture), "--format", "kvh-a"]) == 0


@pytest.mark.parametrize("fmt", sorted(FORMATS))
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_the_twins_fixed_field_encoder_writes_the_bytes_encode_writes(fmt: str,
                                                                      axis: int) -> None:
    """The twin's encoder (one template frame, the CRC corrected for the words that
    differ) must give byte for byte the frames of the general `encode`, CRC included."""
    f = FORMATS[fmt]
    rng = np.random.default_rng(axis)
    seq = np.arange(300, 300 + 2000)
    value = rng.standard_normal(seq.size).astype(np.float32) * 100
    extra = {"ax": 0.25, "ay": -1.0, "az": 9.80665}
    rates = np.zeros((seq.size, 3), dtype=np.float32)
    rates[:, axis] = value
    expected = f.encode(seq, rates, temperature=-7, extra=extra)
    got = f.fixed_encoder(axis, temperature=-7, extra=extra).encode(seq, value)
    assert got.tobytes() == expected.tobytes()
    frames, _, stats = decode(got.tobytes(), f)
    assert stats.crc_errors == 0 and np.array_equal(frames.rates[:, axis], value)


def test_crc_rows_equal_the_bytewise_crc_when_a_repeated_word_changes_late() -> None:
    """compute_rows folds words that repeat in every row into one constant; a word equal
    over the first rows but different in a later one must still be gathered row by row."""
    rng = np.random.default_rng(5)
    rows = np.tile(rng.integers(0, 256, 32, dtype=np.uint8), (3000, 1))
    rows[:, 12:16] = rng.integers(0, 256, (3000, 4), dtype=np.uint8)  # a varying field
    rows[2500, 3] ^= 0x10        # the header word differs in one late row only
    rows[2999, 31] ^= 0x01       # and the last word in the last row
    got = CRC32_MPEG2.compute_rows(rows)
    for i in (0, 1, 2499, 2500, 2501, 2999):
        assert int(got[i]) == CRC32_MPEG2.compute(rows[i].tobytes())
