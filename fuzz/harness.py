"""The one fuzz-target helper: what a target is, how an input is judged, where crashes go.

Every target asserts one invariant: any input decodes or raises its layer's
peer-error type (``RemoteProtocolError`` for yarp_lite, ``BridgeProtocolError``
for the bridge, ``ConfigError`` for the XML configuration).  Any other
exception -- including an ``AssertionError`` a target raises when a decoded
value breaks a promise (it does not re-encode, a decoder half-consumed) -- is a
*crash*: its input is saved under ``fuzz/crashers/<target>/`` with the
traceback beside it, and it becomes a regular test in the module's test file.

This module imports nothing from the code under test, so the atheris worker
can import the targets inside its instrumentation hook.
"""

from __future__ import annotations

import hashlib
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Type, TypeVar

ROOT = Path(__file__).resolve().parents[1]
CRASHERS = ROOT / "fuzz" / "crashers"
#: Inputs kept per crash signature (the first ones found).
KEEP_PER_SIGNATURE = 3

Errors = Tuple[Type[BaseException], ...]
T = TypeVar("T")


@dataclass(frozen=True)
class Target:
    """One decoder under fuzz: ``run`` feeds it an input, ``expected`` is its peer error."""

    name: str
    run: Callable[[bytes], None]
    expected: Errors
    seeds: Callable[[], List[bytes]]
    max_len: int = 4096
    doc: str = ""


@dataclass(frozen=True)
class Crash:
    """An input that made a target raise something other than its peer error."""

    target: str
    data: bytes
    signature: str          # exception type @ innermost project frame: one per bug
    report: str             # the traceback

    @classmethod
    def from_exception(cls, target: str, data: bytes, exc: BaseException) -> "Crash":
        frames = traceback.extract_tb(exc.__traceback__)
        ours = [frame for frame in frames if _is_project_file(frame.filename)]
        where = ours[-1] if ours else (frames[-1] if frames else None)
        place = f"{_relative(where.filename)}:{where.lineno}" if where else "?"
        report = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
        return cls(target, data, f"{type(exc).__name__}@{place}", report)


def _is_project_file(filename: str) -> bool:
    path = Path(filename)
    return ROOT in path.parents and "site-packages" not in path.parts and \
        path.parts[len(ROOT.parts)] != "fuzz"


def _relative(filename: str) -> str:
    path = Path(filename)
    return str(path.relative_to(ROOT)) if ROOT in path.parents else path.name


def execute(target: Target, data: bytes) -> Optional[Crash]:
    """Run one input; None when it decoded or raised the target's peer error."""
    try:
        target.run(data)
    except target.expected:
        return None
    except Exception as exc:  # not hidden: every other exception is the finding we record
        return Crash.from_exception(target.name, data, exc)
    return None


def attempt(errors: Errors, function: Callable[..., T], *args) -> Optional[T]:
    """``function(*args)``, or None if it raised one of the peer ``errors``.

    Lets a target go on after an expected refusal (the rest of a stream, the
    next datagram) while anything unexpected still escapes.
    """
    try:
        return function(*args)
    except errors:
        return None


# -- input shapes shared by the targets ------------------------------------------------


def split_records(data: bytes) -> List[bytes]:
    """Cut an input into records: 2-byte little-endian length, then that many bytes."""
    records, pos = [], 0
    while pos + 2 <= len(data):
        length = int.from_bytes(data[pos:pos + 2], "little")
        records.append(data[pos + 2:pos + 2 + length])
        pos += 2 + length
    return records


def join_records(records: Sequence[bytes]) -> bytes:
    """The inverse of :func:`split_records` (to build seeds)."""
    return b"".join(len(record).to_bytes(2, "little") + record for record in records)


# -- crashers on disk ----------------------------------------------------------------


def crash_dir(target: str) -> Path:
    return CRASHERS / target


def known_signatures(target: str) -> Dict[str, int]:
    """Signatures already saved for ``target`` (first line of each report) and counts."""
    counts: Dict[str, int] = {}
    directory = crash_dir(target)
    if directory.is_dir():
        for report in directory.glob("*.txt"):
            signature = report.read_text().split("\n", 1)[0]
            counts[signature] = counts.get(signature, 0) + 1
    return counts


def save(crash: Crash, counts: Dict[str, int]) -> Optional[Path]:
    """Write the input and its report, unless this signature has enough examples."""
    if counts.get(crash.signature, 0) >= KEEP_PER_SIGNATURE:
        return None
    counts[crash.signature] = counts.get(crash.signature, 0) + 1
    directory = crash_dir(crash.target)
    directory.mkdir(parents=True, exist_ok=True)
    stem = hashlib.sha1(crash.signature.encode()).hexdigest()[:8] + "-" + \
        hashlib.sha1(crash.data).hexdigest()[:12]
    (directory / f"{stem}.bin").write_bytes(crash.data)
    (directory / f"{stem}.txt").write_text(f"{crash.signature}\n\n{crash.report}")
    return directory / f"{stem}.bin"


@dataclass
class Tally:
    """What a campaign found: inputs run, time spent, crash signatures seen."""

    target: str
    inputs: int = 0
    seconds: float = 0.0
    signatures: Dict[str, int] = field(default_factory=dict)   # signature -> hits
    new: List[str] = field(default_factory=list)               # not saved before this run
    first: Dict[str, Crash] = field(default_factory=dict)      # one crash per signature

    def record(self, crash: Crash, saved_before: Dict[str, int]) -> None:
        if crash.signature not in self.signatures:
            self.first[crash.signature] = crash
            if crash.signature not in saved_before:
                self.new.append(crash.signature)
        self.signatures[crash.signature] = self.signatures.get(crash.signature, 0) + 1

    @property
    def rate(self) -> float:
        return self.inputs / self.seconds if self.seconds > 0 else 0.0
