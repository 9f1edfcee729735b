"""``python -m system.pi_start_loop``: start the PI again and again, kill its 3-D view, count.

Issue 31: librviz under llvmpipe used to take the whole PI down about once in
20-30 starts.  This runs, on a private Xvfb display and name servers of its own
(a roscore and a yarp-lite server, no robot), with ``--burners`` processes
spinning ``while 1: pass`` beside it:

1. the **kill loop** (first, being the shorter: an interrupted run still has both
   figures): one PI whose render process is SIGKILLed ``--kills`` times; each
   time the time from the kill to the PI's ``3-D view up`` line of the new
   process (both wall-clock: the PI's lines carry their time), and librviz's
   picture on the screen again.  The next kill waits ``--settle`` s after the
   view is back (a view that dies within 2 s of its window counts toward
   :class:`pilot.view3d_process.RestartPolicy`'s back-off);
2. the **start loop**: ``walkman-pilot --layout main-pilot`` started ``--starts``
   times; each time it waits for the 3-D view's window (the PI's log line
   ``3-D view up``), watches ``--hold`` s more (the old crash came a second or
   two after the window appeared), checks the PI is alive and librviz's picture
   is on the screen, and stops it with SIGTERM (as closing it does), checking
   it exits 0 and leaves no render process behind.

It prints one line per start and kill and the figures at the end: PI deaths,
render-process crashes (librviz's own, now harmless: their stacks and cores
are kept), times to the view and back.  Exit status 1 if a PI died or a view
did not come back.  Screenshots of the first kill go to ``--out``.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import List, Optional, Sequence

from system.display import display_env, private_display
from system.processes import Proc, WaitTimeout
from system.topology import Pc

PYTHON = sys.executable
#: The PI's line when a render process's window is up (its time first: WALKMAN_LOG_TIME).
VIEW_UP = re.compile(r"^(\d+\.\d+) \[pilot\] INFO pilot\.view3d: pilot: 3-D view up "
                     r"\(pid (\d+)")
VIEW_DIED = re.compile(r"^(\d+\.\d+) .*3-D view \(pid (\d+)\) (crashed|was killed|exited|hung)"
                       r"([^;]*)")
BACKGROUND = (40, 44, 52)       # RViz's, pilot.view3d_child.RVIZ_CONFIG
#: Background pixels that mean librviz's picture is on the screen (the view is ~500x250).
PICTURE_PIXELS = 20_000


@dataclass
class Figures:
    starts: int = 0
    pi_deaths: List[str] = field(default_factory=list)
    stop_failures: List[str] = field(default_factory=list)
    no_view: List[str] = field(default_factory=list)
    view_up: List[float] = field(default_factory=list)       # PI start -> view up, s
    view_deaths: List[str] = field(default_factory=list)     # librviz's own, in either loop
    crash_back: List[float] = field(default_factory=list)     # noticed -> next view up, s
    kills: int = 0
    back: List[float] = field(default_factory=list)           # kill -> new view up, s
    not_back: List[str] = field(default_factory=list)
    loads: List[float] = field(default_factory=list)


class Screen:
    """Pictures of the private display, through Qt (no ImageMagick needed)."""

    def __init__(self, display: str) -> None:
        os.environ.update(display_env(display))
        from python_qt_binding.QtWidgets import QApplication

        self.app = QApplication.instance() or QApplication(["pi_start_loop"])

    def grab(self):
        return self.app.primaryScreen().grabWindow(0).toImage()

    def picture_shown(self, save: Optional[Path] = None) -> bool:
        """librviz's background covers a view's worth of the screen."""
        import numpy as np
        from python_qt_binding.QtGui import QImage

        image = self.grab().convertToFormat(QImage.Format_RGB32)
        if save is not None:
            image.save(str(save))
        bits = image.constBits()
        bits.setsize(image.sizeInBytes())
        pixels = np.frombuffer(bits, np.uint8).reshape(image.height(), image.bytesPerLine())
        bgr = pixels[:, :image.width() * 4].reshape(image.height(), image.width(), 4)[..., :3]
        distance = np.abs(bgr.astype(np.int16) - np.array(BACKGROUND[::-1], np.int16)).sum(axis=2)
        return int((distance < 12).sum()) >= PICTURE_PIXELS


def view_ups(pi: Proc) -> List[tuple]:
    """(wall time, pid) of every ``3-D view up`` line so far."""
    return [(float(m.group(1)), int(m.group(2))) for m in map(VIEW_UP.search, list(pi.lines))
            if m]


def wait_view_up(pi: Proc, after: int, timeout: float) -> tuple:
    """The ``after``+1-th view-up line; raises WaitTimeout (or if the PI exits)."""
    deadline = time.monotonic() + timeout
    while True:
        ups = view_ups(pi)
        if len(ups) > after:
            return ups[after]
        if pi.popen.poll() is not None:
            raise WaitTimeout(f"the PI exited ({pi.popen.returncode}) before its 3-D view")
        if time.monotonic() > deadline:
            raise WaitTimeout(f"no 3-D view within {timeout:g} s")
        time.sleep(0.02)


def wait_picture(screen: Screen, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if screen.picture_shown():
            return True
        time.sleep(0.2)
    return False


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as stat:           # a zombie is dead
        return stat.read().rsplit(")", 1)[1].split()[0] != "Z"


def start_pi(pc: Pc, name: str) -> Proc:
    return pc.start(name, [PYTHON, "-m", "pilot.app", "--layout", "main-pilot", "--name", name])


def count_view_deaths(pi: Proc, figures: Figures, where: str, skip_killed: bool) -> None:
    """The render process's deaths we did not cause, and how long the PI took to notice
    (the kernel writes the core first) and to show the next view."""
    ups = view_ups(pi)
    for m in map(VIEW_DIED.search, list(pi.lines)):
        if m and not (skip_killed and m.group(3) == "was killed"):
            noticed = float(m.group(1))
            back = next((at - noticed for at, _ in ups if at > noticed), None)
            if back is not None:
                figures.crash_back.append(back)
            figures.view_deaths.append(
                f"{where}: pid {m.group(2)} {m.group(3)}{m.group(4)}; the next view up "
                + (f"{back:.2f} s after the PI noticed" if back is not None else "never"))


def stop_pi(pi: Proc, figures: Figures, where: str) -> None:
    """SIGTERM, as closing the window; it must exit 0 and take its render process along."""
    children = [pid for _, pid in view_ups(pi)]
    os.kill(pi.popen.pid, signal.SIGTERM)
    try:
        code = pi.wait(30)
    except subprocess.TimeoutExpired:
        figures.stop_failures.append(f"{where}: did not exit within 30 s of SIGTERM")
        pi.kill()
        return
    if code != 0:   # its last lines say why (one in 500 exited 1: the cause was not kept)
        tail = "\n    ".join(pi.output().splitlines()[-15:])
        figures.stop_failures.append(f"{where}: exited {code} when stopped; its last lines:\n"
                                     f"    {tail}")
    deadline = time.monotonic() + 10
    while children and any(alive(p) for p in children) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [p for p in children if alive(p)]
    if left:
        figures.stop_failures.append(f"{where}: render process {left} outlived the PI")
        for pid in left:
            os.kill(pid, signal.SIGKILL)


def start_loop(pc: Pc, screen: Screen, figures: Figures, starts: int, hold: float) -> None:
    for index in range(1, starts + 1):
        figures.starts = index
        figures.loads.append(os.getloadavg()[0])
        pi = start_pi(pc, f"pi_loop{index}")
        began = time.time()
        where = f"start {index}"
        try:
            at, pid = wait_view_up(pi, 0, 180)
        except WaitTimeout as exc:
            if pi.popen.poll() is not None:
                figures.pi_deaths.append(f"{where}: {exc}\n" + "\n".join(pi.lines[-30:]))
            else:
                figures.no_view.append(f"{where}: {exc}")
                stop_pi(pi, figures, where)
            print(f"{where}: FAILED {exc}", flush=True)
            continue
        figures.view_up.append(at - began)
        time.sleep(hold)        # the old crash came a second or two after the window
        shown = screen.picture_shown()
        if pi.popen.poll() is not None:
            figures.pi_deaths.append(f"{where}: the PI died ({pi.popen.returncode}) after its "
                                     f"3-D view was up\n" + "\n".join(pi.lines[-30:]))
            print(f"{where}: PI DIED {pi.popen.returncode}", flush=True)
            continue
        if not shown and not wait_picture(screen, 30):
            figures.no_view.append(f"{where}: no librviz picture on the screen")
        count_view_deaths(pi, figures, where, skip_killed=False)
        stop_pi(pi, figures, where)
        pc.processes.pop(f"pi_loop{index}", None)
        print(f"{where}: PI alive, view up {at - began:.2f} s after the PI's start "
              f"(pid {pid}), picture {'shown' if shown else 'late'}; load "
              f"{figures.loads[-1]:.1f}", flush=True)


def kill_loop(pc: Pc, screen: Screen, figures: Figures, kills: int, settle: float,
              out: Path) -> None:
    pi = start_pi(pc, "pi_kills")
    try:
        wait_view_up(pi, 0, 180)
        wait_picture(screen, 60)
        while figures.kills < kills:
            time.sleep(settle)
            ups = view_ups(pi)
            seen, pid = len(ups), ups[-1][1]
            first = figures.kills == 0
            if first:
                screen.picture_shown(out / "kill-before.png")
            killed_at = time.time()
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:      # it died by itself (librviz): its successor comes
                print(f"render process {pid} died by itself; waiting for the next",
                      flush=True)
                wait_view_up(pi, seen, 120)
                continue
            figures.kills += 1
            figures.loads.append(os.getloadavg()[0])
            if first:
                time.sleep(0.3)
                screen.picture_shown(out / "kill-restarting.png")
            try:
                at, new = wait_view_up(pi, seen, 180)
            except WaitTimeout as exc:
                figures.not_back.append(f"kill {figures.kills}: {exc}")
                print(f"kill {figures.kills}: NOT BACK {exc}", flush=True)
                break
            figures.back.append(at - killed_at)
            shown = wait_picture(screen, 30)
            if first:
                screen.picture_shown(out / "kill-after.png")
            if not shown:
                figures.not_back.append(f"kill {figures.kills}: pid {new} up but no picture")
            print(f"kill {figures.kills}: pid {pid} -> {new}, back in {at - killed_at:.2f} s; "
                  f"load {figures.loads[-1]:.1f}", flush=True)
        if pi.popen.poll() is not None:
            figures.pi_deaths.append(f"kill loop: the PI died ({pi.popen.returncode})\n"
                                     + "\n".join(pi.lines[-30:]))
        count_view_deaths(pi, figures, "kill loop", skip_killed=True)
    finally:
        if pi.popen.poll() is None:
            stop_pi(pi, figures, "kill loop")


def spread(values: Sequence[float]) -> str:
    if not values:
        return "none"
    ordered = sorted(values)
    p95 = ordered[min(len(ordered) - 1, int(round(0.95 * (len(ordered) - 1))))]
    return (f"median {statistics.median(ordered):.2f} s, p95 {p95:.2f} s, "
            f"max {ordered[-1]:.2f} s (n={len(ordered)})")


def report(figures: Figures, burners: int, state: Path) -> int:
    print("\n== figures ==")
    print(f"burners: {burners}; load average (1 min) during the run: "
          f"{spread(figures.loads).replace(' s', '')}")
    print(f"starts: {figures.starts}; PI deaths: {len(figures.pi_deaths)}; "
          f"failed stops: {len(figures.stop_failures)}; starts without a view: "
          f"{len(figures.no_view)}")
    print(f"3-D view up after the PI's start: {spread(figures.view_up)}")
    print(f"kills: {figures.kills}; back: {spread(figures.back)}; over 3 s: "
          f"{sum(1 for b in figures.back if b > 3.0)}; not back: {len(figures.not_back)}")
    print(f"render-process deaths not ours (librviz's crashes, survived): "
          f"{len(figures.view_deaths)}; the next view up after each: "
          f"{spread(figures.crash_back)}")
    for line in figures.pi_deaths + figures.stop_failures + figures.no_view + \
            figures.not_back + figures.view_deaths:
        print(f"  {line}")
    kept = sorted(p for p in (state / "walkman-pilot" / "view3d").glob("pid*") if p.is_dir())
    print(f"crash folders kept (stacks, cores): {len(kept)}"
          + "".join(f"\n  {p}: {', '.join(sorted(f.name for f in p.iterdir()))}" for p in kept))
    return 1 if figures.pi_deaths or figures.not_back else 0


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m system.pi_start_loop",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--starts", type=int, default=500)
    parser.add_argument("--kills", type=int, default=50)
    parser.add_argument("--burners", type=int, default=2, help="CPU burners beside the PI")
    parser.add_argument("--hold", type=float, default=3.0,
                        help="seconds each started PI is watched after its view is up")
    parser.add_argument("--settle", type=float, default=2.5,
                        help="seconds the view stays up between two kills")
    parser.add_argument("--out", type=Path, default=Path("out") / "pi-start-loop")
    options = parser.parse_args(argv)
    options.out.mkdir(parents=True, exist_ok=True)
    for sig in (signal.SIGINT, signal.SIGTERM):    # (a background job ignores SIGINT)
        signal.signal(sig, signal.default_int_handler)
    root = Path(tempfile.mkdtemp(prefix="pi-start-loop-"))
    burners = [subprocess.Popen([PYTHON, "-c", "while 1: pass"])
               for _ in range(options.burners)]
    figures = Figures()
    pc = Pc("loop", root, log_dir=options.out / "logs")     # every PI's output, stamped
    pc.extra_env.update({"WALKMAN_LOG_TIME": "1", "PYTHONFAULTHANDLER": "1"})
    try:
        with private_display() as display:
            pc.extra_env.update(display_env(display))
            pc.start_name_servers()
            screen = Screen(display)
            print(f"pi_start_loop: Xvfb {display}, name servers in {root}, "
                  f"{options.burners} burner(s)", flush=True)
            # the kills first: the shorter loop, so an interrupted run still has both figures
            kill_loop(pc, screen, figures, options.kills, options.settle, options.out)
            start_loop(pc, screen, figures, options.starts, options.hold)
    except KeyboardInterrupt:
        print("interrupted: the figures so far", flush=True)
    finally:
        for burner in burners:
            burner.kill()
        pc.close()
    return report(figures, options.burners, root / "state")


if __name__ == "__main__":
    sys.exit(main())
