"""A bag cut at 50 random offsets and corrupted in 50 random places: every message before the damage is
read, nothing is invented, the loss is counted exactly, and nothing raises or hangs."""
from __future__ import annotations

import random
from pathlib import Path

import pytest

from bagdamage import locate, read_damaged, write_bag

pytestmark = pytest.mark.timeout(120)
SEED = 20261123


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


def check_accounting(located, delivered, report) -> None:
    """Nothing invented, and exactly the messages not delivered are reported missing."""
    everything = {(m.topic, m.log_time, m.data) for m in located}
    assert set(delivered) <= everything, "a message that is not in the bag"
    assert len(delivered) == len(set(delivered)), "a message delivered twice"
    assert report.missing == len(everything) - len(delivered)
    assert report.complete == (len(delivered) == len(everything)) or report.damage


def test_cut_at_50_random_offsets(bag, original, tmp_path):
    content, located = original
    rng = random.Random(SEED)
    for cut in sorted(rng.randrange(8, len(content)) for _ in range(50)):
        delivered, report = read_damaged(bag, tmp_path, content[:cut])
        assert delivered is not None, cut
        before = {(m.topic, m.log_time, m.data) for m in located if m.end <= cut}
        assert before <= set(delivered), f"cut at {cut}: {len(before - set(delivered))} complete messages lost"
        check_accounting(located, delivered, report)


def test_corrupt_in_50_random_places(bag, original, tmp_path):
    content, located = original
    rng = random.Random(SEED + 1)
    for _ in range(50):
        place, burst = rng.randrange(len(content)), rng.randint(1, 16)
        damaged = bytearray(content)
        for k in range(place, min(place + burst, len(content))):
            damaged[k] ^= rng.randint(1, 255)
        delivered, report = read_damaged(bag, tmp_path, bytes(damaged))
        if place < 8:  # the magic: not an MCAP file any more, refused as a whole with a reason
            assert delivered is None
            continue
        assert delivered is not None, place
        # a chunk's CRC says it is damaged, not where: the chunk the damage touches is the unit lost
        untouched = {(m.topic, m.log_time, m.data) for m in located
                     if m.chunk[1] <= place or m.chunk[0] >= place + burst}
        assert untouched <= set(delivered), f"damage at {place}: {len(untouched - set(delivered))} intact lost"
        check_accounting(located, delivered, report)


def test_without_a_usable_index_reading_resumes_after_a_broken_chunk(bag, original, tmp_path):
    """The summary fails its CRC and a chunk's length field is garbage: the file is walked from the
    start and picked up again at the next chunk whose CRC checks."""
    content, located = original
    chunks = sorted({m.chunk for m in located})
    broken, following = chunks[len(chunks) // 2], chunks[len(chunks) // 2 + 1]
    damaged = bytearray(content)
    damaged[broken[0] + 1:broken[0] + 9] = (2 ** 40).to_bytes(8, "little")  # claims a terabyte
    summary_start = int.from_bytes(content[-8 - 20:-8 - 12], "little")  # the footer's first field
    damaged[summary_start + 20] ^= 0xFF
    delivered, report = read_damaged(bag, tmp_path, bytes(damaged))
    assert any("summary section damaged" in note for note in report.notes)
    expected = {(m.topic, m.log_time, m.data) for m in located if m.chunk != broken}
    assert set(delivered) == expected
    assert any(f"reading went on at the chunk at byte {following[0]}" in line for line in report.damage), report.damage
    check_accounting(located, delivered, report)
