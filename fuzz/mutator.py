"""A small deterministic mutation fuzzer: the CI engine, and the fallback without atheris.

It is not coverage-guided: it mutates the seed corpus (bit flips, interesting
bytes and integers, insertions, deletions, copies, splices, truncations) with
a seeded ``random.Random``, so a given ``(target, budget, seed)`` always runs
the same inputs.  The seeds themselves run first.  atheris (libFuzzer) is the
engine for long campaigns (``fuzz/run.py``): it keeps inputs that reach new
code and finds deeper paths.
"""

from __future__ import annotations

import random
import time
from typing import Iterator, List, Optional

from fuzz.harness import Crash, Target, Tally, execute, known_signatures, save

_INTERESTING_BYTES = (0x00, 0x01, 0x02, 0x0F, 0x10, 0x7F, 0x80, 0x81, 0xFE, 0xFF)
_INTERESTING_INTS = (0, 1, -1, 2, 15, 16, 127, 128, 255, 256, 1000, 4096, 65535, 65536,
                     (1 << 31) - 1, -(1 << 31), 1 << 30, 256 + 1, 512 + 256)


def mutations(seeds: List[bytes], rng: random.Random, max_len: int) -> Iterator[bytes]:
    """The seeds, then endless mutants of them."""
    corpus = [seed[:max_len] for seed in seeds] or [b""]
    yield from corpus
    while True:
        data = bytearray(rng.choice(corpus))
        for _ in range(rng.randint(1, 4)):
            _mutate(data, corpus, rng)
        yield bytes(data[:max_len])


def _mutate(data: bytearray, corpus: List[bytes], rng: random.Random) -> None:
    op = rng.randrange(9)
    pos = rng.randrange(len(data) + 1)
    if op == 0 and data:
        data[min(pos, len(data) - 1)] ^= 1 << rng.randrange(8)
    elif op == 1 and data:
        data[min(pos, len(data) - 1)] = rng.choice(_INTERESTING_BYTES)
    elif op == 2 and data:
        data[min(pos, len(data) - 1)] = rng.randrange(256)
    elif op == 3:
        data[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 8)))
    elif op == 4 and data:
        del data[pos:pos + rng.randint(1, 16)]
    elif op == 5 and data:
        start = rng.randrange(len(data))
        chunk = data[start:start + rng.randint(1, 32)]
        data[pos:pos] = chunk
    elif op == 6:
        value = rng.choice(_INTERESTING_INTS)
        width = rng.choice((1, 2, 4, 8))
        raw = (value % (1 << (8 * width))).to_bytes(width, rng.choice(("little", "big")))
        data[pos:pos + width] = raw
    elif op == 7:
        other = rng.choice(corpus)
        cut = rng.randrange(len(other) + 1)
        data[pos:] = other[cut:]
    elif op == 8 and data:
        del data[pos:]


def campaign(target: Target, budget: int, seed: int = 0, seconds: Optional[float] = None,
             keep: bool = False) -> Tally:
    """Run ``budget`` inputs (or until ``seconds``); with ``keep``, save crashers to disk."""
    rng = random.Random(f"{target.name}:{seed}")
    tally = Tally(target.name)
    before = known_signatures(target.name) if keep else {}
    counts = dict(before)
    start = time.perf_counter()
    for data in mutations(target.seeds(), rng, target.max_len):
        if tally.inputs >= budget or (seconds is not None and
                                      time.perf_counter() - start >= seconds):
            break
        tally.inputs += 1
        crash: Optional[Crash] = execute(target, data)
        if crash is not None:
            tally.record(crash, before)
            if keep:
                save(crash, counts)
    tally.seconds = time.perf_counter() - start
    return tally
