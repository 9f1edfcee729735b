"""Run a fuzz campaign over every decoder (or some) and print what it found.

    .venv/bin/python -m fuzz.run                       # every target, 100 000 inputs each
    .venv/bin/python -m fuzz.run tiles config --budget 20000 --seconds 60 --seed 3
    .venv/bin/python -m fuzz.run --engine simple       # without atheris
    .venv/bin/python -m fuzz.run --replay              # do the saved crashers still crash?

Engines: ``atheris`` (libFuzzer, coverage-guided; each target runs in its own
worker process, because libFuzzer never returns) and ``simple`` (the
deterministic mutator of :mod:`fuzz.mutator`, in this process).  atheris is
used when it imports.  Each target stops after ``--budget`` inputs or
``--seconds``, whichever comes first.  Crashing inputs are saved under
``fuzz/crashers/<target>/`` with their traceback; libFuzzer's growing corpus
lives in ``fuzz/corpus/<target>/`` (not versioned) and is reused by later runs.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import List, Optional, Sequence

from fuzz.harness import CRASHERS, ROOT, Tally, crash_dir, execute, known_signatures, save

CORPUS = ROOT / "fuzz" / "corpus"
#: A worker killed by libFuzzer (a slow or memory-hungry input) is restarted this often.
MAX_RESTARTS = 3
#: libFuzzer's limits per input: a decoder slower or hungrier than this is a finding.
INPUT_TIMEOUT_SECONDS = 20
RSS_LIMIT_MB = 3072
_ARTIFACTS = ("crash-", "timeout-", "oom-", "leak-", "slow-unit-")


def _have_atheris() -> bool:
    try:
        import atheris  # noqa: F401
    except ImportError:
        return False
    return True


# -- the atheris worker (one process per target) -------------------------------------


def _write_stats(path: Path, tally: Tally) -> None:
    path.write_text(json.dumps({"inputs": tally.inputs, "seconds": tally.seconds,
                                "signatures": tally.signatures, "new": tally.new}))


def _worker(name: str, budget: int, seconds: float, seed: int, stats: Path) -> None:
    import atheris

    with atheris.instrument_imports(include=["bridge", "yarp_lite"]):
        from fuzz.targets import TARGETS
    target = TARGETS[name]
    corpus = CORPUS / name
    corpus.mkdir(parents=True, exist_ok=True)
    for index, data in enumerate(target.seeds()):
        (corpus / f"seed-{index}").write_bytes(data)
    artifacts = crash_dir(name)
    artifacts.mkdir(parents=True, exist_ok=True)
    tally = Tally(name)
    before = known_signatures(name)
    counts = dict(before)
    clock = {"start": 0.0}

    def one(data: bytes) -> None:
        if not tally.inputs:
            clock["start"] = time.perf_counter()
        tally.inputs += 1
        crash = execute(target, data)
        if crash is not None:
            tally.record(crash, before)
            save(crash, counts)
        tally.seconds = time.perf_counter() - clock["start"]
        done = tally.inputs >= budget or tally.seconds >= seconds
        if done or tally.inputs % 2000 == 0:
            _write_stats(stats, tally)
        if done:
            os._exit(0)  # libFuzzer never returns; everything is already on disk

    atheris.Setup([sys.argv[0], f"-seed={seed}", f"-max_len={target.max_len}",
                   f"-timeout={INPUT_TIMEOUT_SECONDS}", f"-rss_limit_mb={RSS_LIMIT_MB}",
                   "-use_value_profile=1", f"-artifact_prefix={artifacts}/", str(corpus)], one)
    atheris.Fuzz()


# -- the parent --------------------------------------------------------------------------


def _run_atheris(name: str, budget: int, seconds: float, seed: int) -> Tally:
    """Run workers until the budget is spent; a worker libFuzzer killed counts as a crash."""
    tally = Tally(name)
    saved_before = known_signatures(name)
    log = CORPUS / f"{name}.log"
    CORPUS.mkdir(parents=True, exist_ok=True)
    for attempt_number in range(MAX_RESTARTS + 1):
        stats = CORPUS / f"{name}.stats.json"
        stats.unlink(missing_ok=True)
        artifacts_before = set(crash_dir(name).glob("*")) if crash_dir(name).is_dir() else set()
        remaining_budget = budget - tally.inputs
        remaining_seconds = seconds - tally.seconds
        with open(log, "a") as out:
            result = subprocess.run(
                [sys.executable, "-m", "fuzz.run", "--worker", name,
                 "--budget", str(remaining_budget), "--seconds", str(remaining_seconds),
                 "--seed", str(seed + attempt_number), "--stats", str(stats)],
                cwd=ROOT, stdout=out, stderr=out, check=False)
        part = json.loads(stats.read_text()) if stats.exists() else \
            {"inputs": 0, "seconds": 0.0, "signatures": {}, "new": []}
        tally.inputs += part["inputs"]
        tally.seconds += part["seconds"]
        for signature, hits in part["signatures"].items():
            tally.signatures[signature] = tally.signatures.get(signature, 0) + hits
        tally.new.extend(s for s in part["new"] if s not in tally.new)
        if result.returncode == 0:
            break
        killed = sorted(path.name for path in set(crash_dir(name).glob("*")) - artifacts_before
                        if path.name.startswith(_ARTIFACTS))
        signature = f"libFuzzer exit {result.returncode}: {', '.join(killed) or 'see ' + log.name}"
        tally.signatures[signature] = tally.signatures.get(signature, 0) + 1
        if signature not in saved_before:
            tally.new.append(signature)
        if tally.inputs >= budget or tally.seconds >= seconds:
            break
    return tally


def _run_simple(name: str, budget: int, seconds: float, seed: int) -> Tally:
    from fuzz.mutator import campaign
    from fuzz.targets import TARGETS

    return campaign(TARGETS[name], budget, seed, seconds, keep=True)


def _table(rows: Sequence[Tally], engine: str) -> str:
    head = f"{'target':<18} {'engine':<8} {'inputs':>9} {'seconds':>8} {'exec/s':>8} " \
           f"{'crashes':>7} {'new':>4}"
    lines = [head, "-" * len(head)]
    for tally in rows:
        lines.append(f"{tally.target:<18} {engine:<8} {tally.inputs:>9} {tally.seconds:>8.1f} "
                     f"{tally.rate:>8.0f} {len(tally.signatures):>7} {len(tally.new):>4}")
    for tally in rows:
        for signature, hits in sorted(tally.signatures.items()):
            mark = "NEW " if signature in tally.new else "    "
            lines.append(f"{mark}{tally.target}: {signature} ({hits} inputs)")
    return "\n".join(lines)


def replay(names: Sequence[str]) -> List[str]:
    """Run every saved crasher of ``names`` again; the lines of those that still crash."""
    from fuzz.targets import TARGETS

    still = []
    for name in names:
        for path in sorted(crash_dir(name).glob("*.bin")):
            crash = execute(TARGETS[name], path.read_bytes())
            if crash is not None:
                still.append(f"{name}/{path.name}: {crash.signature}")
    return still


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fuzz.run", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("targets", nargs="*", help="target names (default: all)")
    parser.add_argument("--budget", type=int, default=100_000, help="inputs per target")
    parser.add_argument("--seconds", type=float, default=3600.0, help="time cap per target")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--engine", choices=("atheris", "simple"),
                        default="atheris" if _have_atheris() else "simple")
    parser.add_argument("--replay", action="store_true",
                        help="rerun the saved crashers instead of fuzzing")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--stats", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        _worker(args.worker, args.budget, args.seconds, args.seed, args.stats)
        return 0
    from fuzz.targets import TARGETS

    names = args.targets or list(TARGETS)
    unknown = [name for name in names if name not in TARGETS]
    if unknown:
        parser.error(f"unknown targets {unknown}; known: {', '.join(TARGETS)}")
    if args.replay:
        still = replay(names)
        print("\n".join(still) or "every saved crasher now decodes or raises its peer error")
        return 1 if still else 0
    run = _run_atheris if args.engine == "atheris" else _run_simple
    rows = []
    for name in names:
        tally = run(name, args.budget, args.seconds, args.seed)
        rows.append(tally)
        print(f"{name}: {tally.inputs} inputs, {tally.rate:.0f}/s, "
              f"{len(tally.signatures)} crash signatures", file=sys.stderr, flush=True)
    print(_table(rows, args.engine))
    print(f"crashers: {CRASHERS.relative_to(ROOT)}/<target>/")
    return 1 if any(tally.signatures for tally in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
