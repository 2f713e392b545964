"""A bag cut at 50 random offsets and corrupted in 50 random places: every message whose bytes lie wholly
before the damage is replayed, none differs from the intact bag's message at its place, the loss is counted
exactly, and nothing raises or hangs (a time limit per case).

The one thing a reader cannot catch is a corrupted number inside a payload that still decodes: without a
per-record checksum, the message holding the damaged bytes may be replayed with altered values. The tests
allow exactly that message to differ, and no other.
"""
from __future__ import annotations

import random
from pathlib import Path

import pytest
from bagdamage import check_replayed, locate, read_damaged, write_bag, write_compressed
from mcap.writer import CompressionType

SEED = 20261123
CASES = 50
_draw = random.Random(SEED)
CUTS = [_draw.random() for _ in range(CASES)]  # where, as a fraction of the file
CORRUPTIONS = [(_draw.random(), _draw.randint(1, 16), _draw.getrandbits(128)) for _ in range(CASES)]  # where, bytes, noise


@pytest.fixture(scope="module")
def bag(tmp_path_factory) -> Path:
    return write_bag(tmp_path_factory.mktemp("damage") / "bag")


@pytest.fixture(scope="module")
def original(bag):
    content = next(bag.glob("*.mcap")).read_bytes()
    return content, locate(content)


def test_the_bag_has_many_bounded_chunks(original):
    content, located = original
    chunks = {m.chunk for m in located}
    assert len(located) == 1200 and len(chunks) >= 12
    for chunk in chunks:
        times = [m.log_time for m in located if m.chunk == chunk]
        assert max(times) - min(times) <= 1_000_000_000 and chunk[1] - chunk[0] <= 2 ** 20 + 2 ** 16


def corrupt(content: bytes, fraction: float, burst: int, noise: int) -> tuple[bytes, int, int]:
    """`content` with `burst` bytes from `fraction` of the way in XORed with non-zero noise; the damaged range."""
    place = 8 + int(fraction * (len(content) - 8))
    end = min(place + burst, len(content))
    damaged = bytearray(content)
    for k in range(place, end):
        damaged[k] ^= (noise >> (8 * (k - place)) & 0xFF) or 0xFF
    return bytes(damaged), place, end


@pytest.mark.timeout(10)
@pytest.mark.parametrize("fraction", CUTS, ids=[f"cut{k}" for k in range(CASES)])
def test_cut_at_a_random_offset(bag, original, tmp_path, fraction):
    content, located = original
    cut = 8 + int(fraction * (len(content) - 8))
    delivered, report = read_damaged(bag, tmp_path, content[:cut])
    assert delivered is not None, cut
    assert check_replayed(located, delivered, report, (cut, len(content))) == 0  # a cut alters no byte


@pytest.mark.timeout(10)
@pytest.mark.parametrize("case", CORRUPTIONS, ids=[f"corrupt{k}" for k in range(CASES)])
def test_corrupt_in_a_random_place(bag, original, tmp_path, case):
    content, located = original
    damaged, place, end = corrupt(content, *case)
    delivered, report = read_damaged(bag, tmp_path, damaged)
    assert delivered is not None, place
    check_replayed(located, delivered, report, (place, end))
    untouched = {(m.topic, m.log_time, m.data) for m in located if m.chunk[1] <= place or m.chunk[0] >= end}
    assert untouched <= set(delivered), f"damage at {place}: {len(untouched - set(delivered))} intact lost"


def test_damaged_chunks_give_up_their_messages_before_the_damage(bag, original, tmp_path):
    """Over the 50 corruptions that land inside a chunk's records, the messages before the damage in that
    chunk are replayed (a whole-chunk loss would replay none of them), and the ones lost are counted."""
    content, located = original
    salvaged = lost = 0
    for case in CORRUPTIONS:
        damaged, place, end = corrupt(content, *case)
        hit = [m for m in located if m.chunk[0] <= place < m.chunk[1]]
        if not hit or place < min(m.start for m in hit):
            continue
        delivered, report = read_damaged(bag, tmp_path, damaged)
        replayed = {(topic, log_time) for topic, log_time, _ in delivered}
        salvaged += sum((m.topic, m.log_time) in replayed for m in hit)
        lost += sum(report.lost.values())
    assert salvaged > 0.4 * CASES * len(located) / len({m.chunk for m in located}), salvaged
    assert lost > 0


def test_without_a_usable_index_a_chunk_with_a_broken_length_is_salvaged(bag, original, tmp_path):
    """The summary fails its CRC and a chunk's record length is garbage: the file is walked from the start,
    the broken chunk's records are read from its own records length and checked against its message index,
    and reading goes on at the next chunk whose CRC checks."""
    content, located = original
    chunks = sorted({m.chunk for m in located})
    broken, following = chunks[len(chunks) // 2], chunks[len(chunks) // 2 + 1]
    damaged = bytearray(content)
    damaged[broken[0] + 1:broken[0] + 9] = (2 ** 40).to_bytes(8, "little")  # claims a terabyte
    summary_start = int.from_bytes(content[-8 - 20:-8 - 12], "little")  # the footer's first field
    damaged[summary_start + 20] ^= 0xFF
    delivered, report = read_damaged(bag, tmp_path, bytes(damaged))
    assert any("summary section damaged" in note for note in report.notes)
    assert sorted(delivered) == sorted((m.topic, m.log_time, m.data) for m in located)
    assert any(f"reading went on at the chunk at byte {following[0]}" in line for line in report.damage), report.damage
    assert sum(report.lost.values()) == 0 and report.missing == 0


@pytest.mark.timeout(60)
@pytest.mark.parametrize("compression", [CompressionType.ZSTD, CompressionType.LZ4])
def test_compressed_chunks_cut_and_corrupted(bag, tmp_path, compression):
    """mcap's writer compresses its chunks (zstd by default; 1 MiB of records, so several zstd or lz4 blocks
    each): a cut chunk gives up the blocks that decompress before the cut, a corrupted one what decompresses
    before the damage; nothing is invented."""
    compressed = write_compressed(bag, tmp_path / "compressed", compression)
    content = next(compressed.glob("*.mcap")).read_bytes()
    located = locate(content)
    draw = random.Random(SEED + compression.value)
    from_cut_chunks = 0
    for _ in range(10):
        cut = 8 + int(draw.random() * (len(content) - 8))
        delivered, report = read_damaged(compressed, tmp_path, content[:cut])
        assert check_replayed(located, delivered, report, (cut, len(content))) == 0
        replayed = {(topic, log_time) for topic, log_time, _ in delivered}
        from_cut_chunks += sum((m.topic, m.log_time) in replayed for m in located if m.start < cut < m.end)
    for _ in range(10):
        damaged, place, end = corrupt(content, draw.random(), draw.randint(1, 16), draw.getrandbits(128))
        delivered, report = read_damaged(compressed, tmp_path, damaged)
        check_replayed(located, delivered, report, (place, end))
    assert from_cut_chunks > 0


@pytest.mark.parametrize("alteration", ["log time + 1 ns", "channel id", "string length"])
def test_an_altered_record_that_still_parses_ends_the_salvage(bag, original, tmp_path, alteration):
    """A message in the middle of a chunk altered so that its record still parses: the index's log time and
    channel, or the payload's decoding, catch it; the chunk's messages before it are replayed, it and the rest
    of the chunk are counted as lost."""
    content, located = original
    chunk = sorted({m.chunk for m in located})[3]
    inside = [m for m in located if m.chunk == chunk]
    target = next(m for m in inside[len(inside) // 2:] if m.topic == "/winch/joint_states")
    damaged = bytearray(content)
    if alteration == "log time + 1 ns":
        damaged[target.start + 15:target.start + 23] = (target.log_time + 1).to_bytes(8, "little")
    elif alteration == "channel id":
        other = next(m for m in located if m.topic != target.topic)
        damaged[target.start + 9:target.start + 11] = content[other.start + 9:other.start + 11]
    else:  # the header's frame_id length, after the encapsulation and the stamp
        damaged[target.start + 31 + 12:target.start + 31 + 16] = (2 ** 20).to_bytes(4, "little")
    delivered, report = read_damaged(bag, tmp_path, bytes(damaged))
    check_replayed(located, delivered, report, (target.start, target.end))
    before = [m for m in inside if m.start < target.start]
    assert {(m.topic, m.log_time) for m in inside} & {d[:2] for d in delivered} == {
        (m.topic, m.log_time) for m in before}
    assert sum(report.lost.values()) == len(inside) - len(before) == report.missing
